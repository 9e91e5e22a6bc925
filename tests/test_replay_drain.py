"""`mrta replay` ends only once what it put has left: a replay that closed its session right
after its last put lost what Zenoh's queues still held (a recorder alone received 16,040 of
20,001 on a loaded machine), so the replay lingers (replay.DRAIN) before it closes."""

from __future__ import annotations

import signal
import threading

import pytest

from mrta_zenoh import codec
from mrta_zenoh.messages import Header, Odometry, Pose2D, Twist
from mrta_zenoh.recording import McapRecorder, read_recording
from mrta_zenoh.tools import replay as replay_mod


def odometry_recording(path, n: int) -> None:
    t = [1_000_000_000_000]

    def log_time() -> int:
        t[0] += 1_000_000  # 1 ms apart
        return t[0]

    enc = codec.encoding_for(Odometry.TYPE_NAME)
    with McapRecorder(path, log_time=log_time) as rec:
        for i in range(n):
            msg = Odometry(Header("robot1", i * 0.001, i), Pose2D(0.0, 0.0, 0.0), Twist(0.0, 0.0))
            rec.sample("robot1/odom", enc, codec.encode(msg))


def test_the_session_is_closed_only_after_the_drain(monkeypatch, tmp_path):
    """Order on a replay's own session: every put, then the drain, then close."""
    events: list[str] = []

    class Bus:
        def publish_raw(self, key, enc, payload):
            events.append("put")

        def __enter__(self):
            return self

        def __exit__(self, *exc):
            events.append("close")

    def wait(stop, seconds):
        events.append(f"wait {seconds}")
        return False

    rec = tmp_path / "r.mcap"
    odometry_recording(rec, 3)
    monkeypatch.setattr(replay_mod, "open_bus", lambda options: Bus())
    monkeypatch.setattr(replay_mod, "wait_for_stop", wait)
    assert replay_mod.run_replay(recording=rec, bus_options=None, speed=0) == 3
    assert events[-2:] == [f"wait {replay_mod.DRAIN}", "close"]
    assert replay_mod.DRAIN > 0


def test_an_interrupted_drain_ends_at_once(monkeypatch, tmp_path):
    """Ctrl-C during the drain closes at once: the drain waits on the replay's stop event."""
    rec = tmp_path / "r.mcap"
    odometry_recording(rec, 3)
    stop = threading.Event()
    stop.set()

    class Bus:
        def publish_raw(self, *a):
            raise AssertionError("nothing goes out once stopped")

        def __enter__(self):
            return self

        def __exit__(self, *exc):
            pass

    monkeypatch.setattr(replay_mod, "open_bus", lambda options: Bus())
    assert replay_mod.run_replay(recording=rec, bus_options=None, speed=0, stop=stop) == 0


@pytest.mark.multiprocess
@pytest.mark.slow  # 10–20 s of wall time; the order above (puts, drain, close) is in the CI tier
def test_a_recorder_gets_every_sample_of_a_replay_as_fast_as_possible(children, tokens,
                                                                       tmp_path):
    """`mrta replay --speed 0` of 20,000 samples beside `mrta record`: the recording holds all
    of them once the replay has exited."""
    n = 20_000
    src, out = tmp_path / "src.mcap", tmp_path / "out.mcap"
    odometry_recording(src, n)
    rec = children.mrta("record", "-o", out, name="record")
    tokens.wait("@mrta/recorder/*", 30, rec)
    replay = children.mrta("replay", str(src), "--speed", "0", name="replay")
    assert replay.wait(120) == 0, replay.stderr
    rec.signal(signal.SIGINT)
    assert rec.wait(60) == 130, rec.stderr  # interrupted, its file closed
    got = sum(1 for key, *_ in read_recording(out) if key == "robot1/odom")
    assert got == n
