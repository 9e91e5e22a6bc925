"""Bounded observers: `mrta view` and the recorder keep per-robot state only for
the application's robots, a scene frame's size does not grow with what others publish, memory
is flat after a flood, and keys invented by the thousand cannot grow a recording's channels.
The flood: 10,000 unknown robots, one burst of 30,000 ground-truth/sonar samples — unbounded, it
leaves the view at +58 MB for good and every `/world` frame at about 2 MB. In-process, manual inputs;
the server side (a client never disconnected by another's flood) is in
tests/test_foxglove_server.py."""

from __future__ import annotations

import gc
import tracemalloc
import pytest

from mrta_zenoh.messages import Header, Odometry, Point2D, PointCloud, Pose2D, Twist
from mrta_zenoh.recording import McapRecorder, read_recording
import mrta_zenoh.recording as recording
from mrta_supervisor.live.foxglove import MAX_SCENE_ROBOTS, FoxgloveOutputs, Scene

TEAM = ["robot1", "robot2", "robot3"]
SONAR = tuple(Point2D(0.1 * i, 0.2) for i in range(16))


def feed(scene: Scene, robots, rounds: int = 1) -> None:
    for k in range(rounds):
        for rid in robots:
            t = float(k)
            scene.on_sample(f"{rid}/ground_truth",
                            Odometry(Header(rid, t, k), Pose2D(k, 1, 0), Twist(0, 0)))
            scene.on_sample(f"{rid}/sonar", PointCloud(Header(rid, t, k), SONAR))


def frame(scene: Scene) -> bytes:
    return scene.update().encode()


def strangers(n: int, first: int = 1000):
    return [f"robot{i}" for i in range(first, first + n)]


def test_the_applications_robots_only_whatever_else_is_on_the_bus():
    """The same frame, byte for byte, as a scene that only ever heard the team; every stranger's
    sample counted."""
    flooded, quiet = Scene(TEAM), Scene(TEAM)
    feed(flooded, TEAM + strangers(10_000))
    feed(quiet, TEAM)
    assert frame(flooded) == frame(quiet)
    assert flooded.ignored == 2 * 10_000
    assert set(flooded.poses) == set(TEAM) == set(flooded.trails) == set(flooded.beams)


def test_without_an_application_the_scene_draws_a_bounded_number_of_robots():
    scene = Scene()
    feed(scene, strangers(10_000), rounds=1)
    assert len(scene.poses) == MAX_SCENE_ROBOTS
    assert scene.ignored == 2 * (10_000 - MAX_SCENE_ROBOTS)
    one = Scene()
    feed(one, strangers(1), rounds=1)
    # a frame of the bound, against a frame of one robot times the bound (and the walls)
    assert len(frame(scene)) <= MAX_SCENE_ROBOTS * len(frame(one)) + 100


def test_a_sonar_with_too_many_points_is_drawn_bounded():
    scene = Scene(["robot1"])
    scene.on_sample("robot1/sonar", PointCloud(Header("robot1", 0.0, 0),
                                               tuple(Point2D(1, i) for i in range(50_000))))
    scene.on_sample("robot1/ground_truth",
                    Odometry(Header("robot1", 0.0, 0), Pose2D(0, 0, 0), Twist(0, 0)))
    assert len(frame(scene)) < 10_000


@pytest.mark.slow
def test_memory_is_flat_after_a_flood():
    """A second burst of 30,000 samples from new strangers leaves the outputs' memory where the
    first one left it (tracemalloc: Python allocations the outputs hold)."""
    outputs = FoxgloveOutputs(lambda *a: None, TEAM)
    for rid in TEAM:
        outputs.on_sample(f"{rid}/ground_truth",
                          Odometry(Header(rid, 0, 0), Pose2D(0, 0, 0), Twist(0, 0)))

    def burst(first):
        for rid in strangers(10_000, first):
            for key, msg in ((f"{rid}/ground_truth", Odometry(Header(rid, 0, 0), Pose2D(0, 0, 0),
                                                               Twist(0, 0))),
                             (f"{rid}/sonar", PointCloud(Header(rid, 0, 0), SONAR)),
                             (f"{rid}/sonar", PointCloud(Header(rid, 0, 0), SONAR))):
                outputs.on_sample(key, msg)
        outputs.scene_frame(10**9)

    tracemalloc.start()
    try:
        burst(10_000)
        gc.collect()
        before = tracemalloc.get_traced_memory()[0]
        burst(20_000)
        gc.collect()
        after = tracemalloc.get_traced_memory()[0]
    finally:
        tracemalloc.stop()
    assert after - before < 200_000, (before, after)


def test_invented_keys_cannot_grow_a_recordings_channels(tmp_path, monkeypatch):
    monkeypatch.setattr(recording, "MAX_CHANNELS", 50)
    from mrta_zenoh import codec
    enc = codec.encoding_for(Twist.TYPE_NAME)
    payload = codec.encode(Twist(0.0, 0.0))
    with McapRecorder(tmp_path / "flood.mcap") as rec:
        for i in range(2_000):
            rec.sample(f"stranger{i}/cmd_vel", enc, payload)
        rec.add("/world", ("x", "jsonschema", b'{"type": "object", "properties": {}}'), "json",
                b"{}")  # the recorder's own channels are never refused
    keys = {k for k, *_ in read_recording(tmp_path / "flood.mcap")}
    assert len(keys) == 50 and rec.refused == 2_000 - 50
