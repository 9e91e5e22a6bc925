"""Recordings in simulated time: log time = the simulator's time as the recorder's
SimClock follows it, held before the first clock sample, runs laid end to end across a
simulator restart, log times never decreasing per channel; the viewer's derived channels
sampled per simulated period, driven by the clock samples (not a wall timer) and skipped,
never queued, when the frame loop falls behind. In-process bus and hand-fed clocks: no
process, no Zenoh session."""

from __future__ import annotations

import json
import struct
import threading
import time
from collections import defaultdict

import pytest
from mcap.reader import make_reader

from mrta_zenoh import codec
from mrta_zenoh import node as node_module
from mrta_zenoh.bus import InProcBus
from mrta_zenoh.clock import SimClock
from mrta_zenoh.keys import CLOCK, CLOCK_SOURCE_TOKEN, RECORDER_TOKEN
from mrta_zenoh.messages import Clock, Header, Odometry, Pose2D, Twist
from mrta_zenoh.recording import HOLD_MAX, McapRecorder, read_recording
from mrta_zenoh.sim_log_time import NS, RESTART_GAP_NS, SimLogTime
from mrta_zenoh.tools import record
from mrta_zenoh.tools.record import run_record
from mrta_supervisor.live import viewer
from mrta_supervisor.live.foxglove import FoxgloveOutputs
from mrta_simulator.messages import Segment, World

S = NS  # one simulated second in log-time nanoseconds


class FakeWall:
    """The SimClock's wall clock, moved by hand (its restart rule counts wall silence)."""

    def __init__(self) -> None:
        self.t = 0.0

    def __call__(self) -> float:
        return self.t


class PolledWall(FakeWall):
    """A FakeWall that counts the reads from other threads than `owner` (the recorder's thread
    asking its clock whether it went quiet), so a test waits for the recorder, never a time."""

    def __init__(self, owner: threading.Thread) -> None:
        super().__init__()
        self.owner, self.reads = owner, 0
        self.read = threading.Condition()

    def __call__(self) -> float:
        if threading.current_thread() is not self.owner:
            with self.read:
                self.reads += 1
                self.read.notify_all()
        return self.t

    def wait_polled(self, n: int) -> None:
        """Return once other threads read the wall `n` more times (at most 30 s)."""
        with self.read:
            target = self.reads + n
            assert self.read.wait_for(lambda: self.reads >= target, 30)


@pytest.fixture
def node_wall(monkeypatch) -> PolledWall:
    """The wall of the SimClock a Node makes (the recorders'), moved by hand: a stopped
    recorder drains until this wall says its clock has been quiet for DRAIN_QUIET."""
    wall = PolledWall(threading.current_thread())
    monkeypatch.setattr(node_module, "SimClock", lambda: SimClock(wall=wall))
    return wall


def read(path):
    """topic → [(log_time, data)] in file order, the schemas, the `mrta` metadata."""
    out, schemas = defaultdict(list), {}
    with open(path, "rb") as f:
        reader = make_reader(f)
        for schema, channel, message in reader.iter_messages(log_time_order=False):
            out[channel.topic].append((message.log_time, message.data))
            schemas[channel.topic] = schema
        meta = {m.name: m.metadata for m in reader.iter_metadata()}
    return out, schemas, meta


def payload(msg) -> tuple[str, bytes]:
    return codec.encoding_for(msg.TYPE_NAME), codec.encode(msg)


# ------------------------------------------------------------------ the time mapping
def test_log_time_is_the_simulated_time_and_none_before_the_first_clock_sample():
    clock = SimClock()
    stamp = SimLogTime(clock)
    assert stamp() is None
    clock.on_clock(0.0, "run1")
    assert stamp() == 0
    clock.on_clock(9.34, "run1")
    assert stamp() == 9_340_000_000
    clock.on_clock(9.30, "run1")  # a late duplicate: time does not go back, nor the log time
    assert stamp() == 9_340_000_000


def test_a_clock_sample_moves_the_clock_before_it_is_stamped():
    clock = SimClock()
    stamp = SimLogTime(clock)
    enc, data = payload(Clock(3.5, "run1"))
    stamp.observe(CLOCK, enc, data)
    assert clock.now() == 3.5 and stamp() == 3_500_000_000
    stamp.observe(CLOCK, enc, b"\xc1not msgpack")  # malformed: ignored, counted elsewhere
    stamp.observe("robot1/odom", enc, payload(Clock(9.0, "run1"))[1])  # not the clock key
    assert clock.now() == 3.5


def test_a_restarted_simulation_continues_one_second_after_the_previous_runs_end():
    wall = FakeWall()
    clock = SimClock(wall=wall)
    stamp = SimLogTime(clock)
    for k in range(101):  # run 1: 0 … 2 s
        clock.on_clock(k * 0.02, "run1")
    end = stamp()
    assert end == 2 * S
    wall.t += 5.0  # run1 silent for longer than `silence`: run2 is adopted from its stamp 0
    assert clock.on_clock(0.0, "run2") and clock.restarts == 1
    assert stamp() == end + RESTART_GAP_NS
    clock.on_clock(0.5, "run2")
    assert stamp() == end + RESTART_GAP_NS + S // 2


def test_a_dated_recording_starts_at_the_wall_clock_and_keeps_simulated_durations(tmp_path):
    """--dated: the first clock sample's log time is the wall time it was heard at (a viewer
    shows the run's date, not 1970-01-01); every later one is that plus the simulated time that
    passed, however fast the run went; the file says it is dated."""
    clock = SimClock()
    stamp = SimLogTime(clock, dated=True)
    assert stamp() is None
    before = time.time_ns()
    clock.on_clock(2.0, "run1")
    first = stamp()
    after = time.time_ns()
    assert before - 2 * S <= first - 2 * S <= after  # the origin: when 2.0 s was heard, less 2 s
    for k in range(1, 3001):  # a minute of simulated time, as fast as it comes
        clock.on_clock(2.0 + k * 0.02, "run1")
    assert stamp() - first == 60 * S
    out = tmp_path / "dated.mcap"
    with McapRecorder(out, log_time=stamp):
        pass
    assert read(out)[2]["mrta"] == {"log_time": "simulated", "time_origin": "run_start"}


# ------------------------------------------------------------------ the recorder
def test_the_recorder_holds_samples_until_the_first_clock_sample_then_logs_them_there(tmp_path):
    clock = SimClock()
    stamp = SimLogTime(clock)
    path = tmp_path / "held.mcap"
    odom = payload(Odometry(Header("robot1", 0.0, 0), Pose2D(1, 2, 0), Twist(0, 0)))
    with McapRecorder(path, log_time=stamp) as rec:
        rec.liveliness("robot1/alliance/agent", True)  # before any clock: held
        rec.sample("robot1/odom", *odom)
        clock.on_clock(7.0, "run1")  # a recorder that joined a run at 7 s
        rec.sample(CLOCK, *payload(Clock(7.0, "run1")))
        clock.on_clock(7.02, "run1")
        rec.sample("robot1/odom", *odom)
    topics, schemas, meta = read(path)
    assert meta["mrta"] == {"log_time": "simulated"}
    assert [t for t, _ in topics["@liveliness/robot1/alliance/agent"]] == [7 * S]
    assert [t for t, _ in topics["robot1/odom"]] == [7 * S, 7_020_000_000]
    records = read_recording(path)
    assert records.log_time == "simulated"
    assert [r[0] for r in records][:2] == ["@liveliness/robot1/alliance/agent", "robot1/odom"]


def test_samples_held_when_no_clock_ever_comes_are_written_at_zero_and_the_hold_is_bounded(
        tmp_path, monkeypatch):
    import mrta_zenoh.recording as recording
    monkeypatch.setattr(recording, "HOLD_MAX", 3)
    path = tmp_path / "never.mcap"
    with McapRecorder(path, log_time=SimLogTime(SimClock())) as rec:
        for k in range(5):
            rec.sample(f"k{k}", "application/octet-stream", b"x")
    topics, _, _ = read(path)
    assert sorted(topics) == [f"k{k}" for k in range(5)]
    assert {t for v in topics.values() for t, _ in v} == {0}
    assert HOLD_MAX >= 1000  # the real bound leaves room for a run's start-up


def test_log_times_never_decrease_on_a_channel_and_a_wall_recording_is_unchanged(tmp_path):
    path = tmp_path / "wall.mcap"
    with McapRecorder(path) as rec:
        for t in (5, 3, 9, 8):  # two receive threads can hand samples over out of order
            rec.sample("a", "application/octet-stream", b"x", t)
        rec.sample("b", "application/octet-stream", b"x", 1)
        before = time.time_ns()
        rec.sample("c", "application/octet-stream", b"x")
    topics, _, meta = read(path)
    assert meta["mrta"] == {"log_time": "wall"}
    assert [t for t, _ in topics["a"]] == [5, 5, 9, 9]
    assert [t for t, _ in topics["b"]] == [1]  # clamped per channel, not across channels
    assert topics["c"][0][0] >= before  # wall time when no time is given


def test_a_restart_gives_one_readable_file_with_the_runs_end_to_end(tmp_path):
    wall = FakeWall()
    clock = SimClock(wall=wall)
    stamp = SimLogTime(clock)
    path = tmp_path / "restart.mcap"
    with McapRecorder(path, log_time=stamp) as rec:
        for source, n in (("run1", 150), ("run2", 100)):
            wall.t += 5.0
            for k in range(n + 1):
                enc, data = payload(Clock(k * 0.02, source))
                stamp.observe(CLOCK, enc, data)
                rec.sample(CLOCK, enc, data)
    records = read_recording(path)
    assert records.complete
    times = [t for _, _, t, _ in records]
    assert times == sorted(times) and times[0] == 0
    assert times[150] == 3 * S and times[151] == 4 * S  # 1 s after run1's end
    assert times[-1] == 6 * S
    stamps = [codec.decode("rosgraph_msgs/Clock", p).stamp for _, _, _, p in records]
    assert stamps[151] == 0.0  # the clock channel keeps each run's own stamps


# ------------------------------------------------------------------ the viewer's frames
class Emitted:
    def __init__(self) -> None:
        self.by_topic = defaultdict(list)
        self.data = defaultdict(list)

    def __call__(self, topic, schema, enc, data, t_ns) -> None:
        self.by_topic[topic].append(t_ns)
        self.data[topic].append(data)


def test_next_tick_is_on_the_simulated_grid_and_skips_what_passed():
    assert viewer.next_tick(0.0, 0.2) == pytest.approx(0.2)
    assert viewer.next_tick(0.2 * 3, 0.2) == pytest.approx(0.8)  # 0.6000000000000001 too
    assert viewer.next_tick(0.59999999999, 0.2) == pytest.approx(0.8)
    assert viewer.next_tick(7.13, 0.5) == pytest.approx(7.5)


def keep_pace(pacer, timeout: float = 5.0) -> None:
    """Let the frame loop take a wake-up just given (tests only: in a run nobody waits)."""
    deadline = time.monotonic() + timeout
    while pacer._event.is_set() and time.monotonic() < deadline:
        time.sleep(0.0005)


def run_frames(clock, stamp, outputs, sup=None, refresh=None, *, feed, **rates):
    """_sim_frames in a thread while `feed(pacer)` moves the clock; returns when fed."""
    pacer = viewer.SimPacer(clock)
    stop = threading.Event()
    th = threading.Thread(target=viewer._sim_frames, args=(
        clock, stamp, pacer, outputs, sup, refresh, stop, lambda: False,
        rates.get("scene", 0.2), rates.get("supervisor", 0.5)), daemon=True)
    th.start()
    try:
        feed(pacer)
    finally:
        time.sleep(0.1)
        stop.set()
        pacer._event.set()
        th.join(5)
    assert not th.is_alive()


def test_derived_frames_follow_the_simulated_clock_at_their_rates():
    clock = SimClock()
    stamp = SimLogTime(clock)
    emitted = Emitted()
    outputs = FoxgloveOutputs(emitted)
    outputs.scene.on_sample("world", WALLS)
    outputs.scene.on_sample("robot1/ground_truth",
                            Odometry(Header("world", 0, 0), Pose2D(1, 1, 0), Twist(0, 0)))
    snaps = []

    class Sup:
        def snapshot(self, now):
            snaps.append(now)
            return {"robots": [{"id": "robot1", "state": "busy", "task": "wander"}],
                    "alarms": []}

    def feed(pacer):
        for k in range(501):  # 10 simulated seconds in 20 ms steps
            clock.on_clock(k * 0.02, "run1")
            pacer.poke()
            keep_pace(pacer)

    run_frames(clock, stamp, outputs, Sup(), clock.now, feed=feed)
    world = emitted.by_topic["/world"]
    assert world == sorted(world)
    assert world[0] == 0 and world[-1] == 10 * S
    assert 45 <= len(world) <= 51  # 5 Hz of simulated time (a late wake-up may merge two)
    assert len(emitted.by_topic["/robots/robot1/pose"]) == len(world)
    state = emitted.by_topic["/supervisor/state"]
    assert 18 <= len(state) <= 21 and state[-1] == 10 * S  # 2 Hz
    assert emitted.by_topic["/robots/robot1/task"] == state


WALLS = World(Header("world", 0.0, 0), "box", (Segment(0, 0, 5, 0), Segment(5, 0, 5, 5)))


def test_the_first_world_frame_waits_for_the_walls_a_second_at_most():
    """The simulator sends its walls once a simulated second; a first frame before them showed
    an empty floor. With walls heard at 0.3 s, the first frame is at 0.4 s (the next 5 Hz
    tick) and has them; with none ever heard, frames start 1 s after the first one asked."""
    for walls_at, first in ((0.3, 0.4), (None, 1.0)):
        clock = SimClock()
        emitted = Emitted()
        outputs = FoxgloveOutputs(emitted)

        def feed(pacer):
            for k in range(151):  # 3 simulated seconds
                if walls_at is not None and abs(k * 0.02 - walls_at) < 1e-9:
                    outputs.scene.on_sample("world", WALLS)
                clock.on_clock(k * 0.02, "run1")
                pacer.poke()
                keep_pace(pacer)

        run_frames(clock, SimLogTime(clock), outputs, feed=feed)
        world = emitted.by_topic["/world"]
        assert world[0] == round(first * S), (walls_at, world[:3])
        if walls_at is not None:  # the wall's far corner (5, 5), as protobuf doubles
            assert struct.pack("<d", 5.0) in emitted.data["/world"][0]


def test_a_slow_frame_loop_never_holds_up_the_bus_and_skips_frames_instead():
    clock = SimClock()
    stamp = SimLogTime(clock)
    emitted = Emitted()
    outputs = FoxgloveOutputs(emitted)
    outputs.scene.on_sample("world", WALLS)
    slow = outputs.scene_frame

    def scene_frame(t_ns):
        time.sleep(0.05)  # a frame far slower than the clock
        slow(t_ns)
    outputs.scene_frame = scene_frame
    took = []

    def feed(pacer):
        t0 = time.monotonic()
        for k in range(1001):  # 20 simulated seconds as fast as they come
            clock.on_clock(k * 0.02, "run1")
            pacer.poke()
        took.append(time.monotonic() - t0)
        time.sleep(0.2)  # the loop catches up with the last time once

    run_frames(clock, stamp, outputs, feed=feed)
    assert took[0] < 0.5  # 1001 samples: the receive path never waited for a frame
    world = emitted.by_topic["/world"]
    assert len(world) < 100 and world == sorted(world)  # skipped, not queued
    assert world[-1] == 20 * S  # the latest time, once


def test_frames_after_a_simulator_restart_follow_the_new_run_after_the_old_one():
    wall = FakeWall()
    clock = SimClock(wall=wall)
    stamp = SimLogTime(clock)
    emitted = Emitted()
    outputs = FoxgloveOutputs(emitted)

    def feed(pacer):
        for source, n in (("run1", 100), ("run2", 100)):
            wall.t += 5.0
            for k in range(n + 1):
                clock.on_clock(k * 0.02, source)
                pacer.poke()
                keep_pace(pacer)

    run_frames(clock, stamp, outputs, feed=feed)
    world = emitted.by_topic["/world"]
    assert world == sorted(world)
    assert 2 * S in world and 3 * S in world and world[-1] == 5 * S  # run2: 3 … 5 s
    assert sum(1 for t in world if t >= 3 * S) >= 8


def started_view(tmp_path, bus_only: bool = False):
    """The recorder (run_view; `bus_only`: run_record, the mission runner's recorder of an
    experiment's run) on an in-process bus in a thread, ready: (bus, the recording's path, its
    stop event, the thread)."""
    bus = InProcBus()
    bus.zid = "inproc"
    out = tmp_path / "view.mcap"
    stop, ready = threading.Event(), threading.Event()
    if bus_only:
        th = threading.Thread(target=run_record, kwargs=dict(
            output=out, key_exprs=["**"], bus_options=None, stop=stop, sim_time=True, bus=bus),
            daemon=True)
        up = threading.Event()
        watch = bus.watch_liveliness(f"{RECORDER_TOKEN}/**", lambda _k, alive: alive and up.set())
        th.start()
        assert up.wait(30)  # its token: subscribed and recording, as the runner waits for it
        watch.close()
        return bus, out, stop, th
    th = threading.Thread(target=viewer.run_view, args=(
        viewer.ViewOptions(app="patrol", port=None, output=out, sim_time=True), None),
        kwargs=dict(stop=stop, on_ready=lambda url: ready.set(), bus=bus), daemon=True)
    th.start()
    assert ready.wait(30)
    return bus, out, stop, th


def test_run_view_records_the_bus_and_the_scene_in_simulated_time(tmp_path, monkeypatch,
                                                                   node_wall):
    """The whole recorder on the in-process bus: clock samples and ground truth in, an MCAP
    file out whose log times are the simulated ones, with frames per simulated second."""
    pacers = []

    class Pacer(viewer.SimPacer):
        def __init__(self, clock):
            super().__init__(clock)
            pacers.append(self)
    monkeypatch.setattr(viewer, "SimPacer", Pacer)
    bus, out, stop, th = started_view(tmp_path)
    token = bus.declare_token(f"{CLOCK_SOURCE_TOKEN}/run1")
    bus.publish("robot1/ground_truth",  # before the clock: held, logged at 0
                Odometry(Header("world", 0.0, 0), Pose2D(0, 0, 0), Twist(0, 0)))
    for k in range(501):  # 10 simulated seconds
        t = k * 0.02
        bus.publish(CLOCK, Clock(t, "run1"))
        if k % 5 == 0:
            bus.publish("robot1/ground_truth",
                        Odometry(Header("world", t, 0), Pose2D(t, 0, 0), Twist(1, 0)))
        keep_pace(pacers[0])
    time.sleep(0.3)
    stop.set()
    node_wall.t += record.DRAIN_QUIET  # the clock has been quiet: the recorder ends
    th.join(30)
    token.close()
    assert not th.is_alive()
    topics, schemas, meta = read(out)
    assert meta["mrta"] == {"log_time": "simulated"}
    for topic, rows in topics.items():
        times = [t for t, _ in rows]
        assert times == sorted(times), topic
        s = schemas[topic]
        assert s is not None and (s.encoding, json.loads(s.data) if s.encoding == "jsonschema"
                                  else None) != ("jsonschema", {"type": "object"}), topic
    truth = [t for t, _ in topics["robot1/ground_truth"]]
    assert truth[0] == 0 and truth[-1] == 10 * S
    world = [t for t, _ in topics["/world"]]
    assert len(world) >= 40 and world[-1] == 10 * S
    assert len(topics["/supervisor/state"]) >= 15
    clock_times = [t for t, _ in topics[CLOCK]]
    clock_stamps = [json.loads(d)["stamp"] for _, d in topics[CLOCK]]
    assert clock_times == [round(s * S) for s in clock_stamps]  # each at its own stamp


def test_while_the_clock_stands_still_the_supervisor_is_still_refreshed_at_the_last_time():
    """A stopped simulator: no scene frames (nothing moves), but the supervisor's channels
    once a wall second (STALL_EVERY, on the clock's hand-moved wall), so a live viewer sees
    `clock_stopped`."""
    wall = FakeWall()
    clock = SimClock(wall=wall)
    stamp = SimLogTime(clock)
    emitted = Emitted()
    outputs = FoxgloveOutputs(emitted)

    class Sup:
        def snapshot(self, now):
            return {"robots": [], "alarms": [{"kind": "clock_stopped", "subject": "", "since": 5}]}

    def feed(pacer):
        for k in range(251):
            clock.on_clock(k * 0.02, "run1")
            pacer.poke()
            keep_pace(pacer)
        at_end = 1  # the regular frame at 5 s
        for step in (10.0, viewer.STALL_EVERY, viewer.STALL_EVERY):  # then nothing for long
            wall.t += step
            at_end += 1
            deadline = time.monotonic() + 30
            while (emitted.by_topic["/supervisor/state"].count(5 * S) < at_end
                   and time.monotonic() < deadline):
                time.sleep(0.005)

    run_frames(clock, stamp, outputs, Sup(), clock.now, feed=feed)
    state = emitted.by_topic["/supervisor/state"]
    assert state.count(5 * S) == 4  # the regular one at 5 s, then one stalled per wall step
    assert emitted.by_topic["/world"][-1] == 5 * S
    assert emitted.by_topic["/world"].count(5 * S) == 1
    assert emitted.by_topic["/supervisor/alarms"] == [0]  # raised once, at the first frame


def test_run_record_in_simulated_time(tmp_path, node_wall):
    """`run_record(sim_time=True)`: the bus alone (no derived channels), in simulated time."""
    from mrta_zenoh.tools.record import run_record

    bus = InProcBus()
    bus.zid = "inproc"
    out = tmp_path / "rec.mcap"
    stop = threading.Event()
    th = threading.Thread(target=run_record, kwargs=dict(
        output=out, key_exprs=["**"], bus_options=None, stop=stop, sim_time=True, bus=bus),
        daemon=True)
    th.start()
    deadline = time.monotonic() + 30
    while not any(t.key.startswith("@mrta/recorder/") for t in bus.network.tokens):
        assert time.monotonic() < deadline
        time.sleep(0.01)
    bus.publish("robot1/ground_truth",
                Odometry(Header("world", 0.0, 0), Pose2D(0, 0, 0), Twist(0, 0)))
    for k in range(1, 151):
        bus.publish(CLOCK, Clock(4.0 + k * 0.02, "run1"))  # joined a run at 4 s
    bus.publish("robot1/ground_truth",
                Odometry(Header("world", 7.0, 0), Pose2D(0, 0, 0), Twist(0, 0)))
    stop.set()
    node_wall.t += record.DRAIN_QUIET  # the clock has been quiet: the recorder ends
    th.join(30)
    assert not th.is_alive()
    records = read_recording(out)
    assert records.log_time == "simulated"
    truth = [t for k, _, t, _ in records if k == "robot1/ground_truth"]
    assert truth == [4_020_000_000, 7 * S]  # held for the first clock sample, then its time


def test_the_derived_json_channels_have_schemas_their_messages_fit():
    """`/supervisor/state` and `/robots/<id>/task` have real schemas, and what is sent on them
    (the snapshot without its nulls: foxglove._without_nulls) fits them."""
    import jsonschema

    from mrta_supervisor.live.api import resolve_application, to_json
    from mrta_supervisor.live.foxglove import ROBOT_TASK, SUPERVISOR_SNAPSHOT
    from mrta_supervisor.live.state import Supervisor

    app, arch = resolve_application("patrol")
    sup = Supervisor(arch, app, 0.0)
    sup.on_liveliness("robot1/alliance/agent", True, 0.5)
    sup.update(1.0)
    sup.on_liveliness("robot1/alliance/agent", False, 2.0)
    sup.update(40.0)
    snap = json.loads(to_json(sup.snapshot(40.0)))
    assert snap["transitions"] and snap["alarms"]
    assert any(r["task"] is None for r in snap["robots"])  # what the schema cannot say
    jsonschema.Draft202012Validator.check_schema(SUPERVISOR_SNAPSHOT)
    emitted = {}
    FoxgloveOutputs(lambda topic, schema, enc, data, t: emitted.setdefault(
        topic, (schema, json.loads(data) if enc == "json" else None))).supervisor_frame(0, snap)
    for topic, (schema, data) in emitted.items():
        if schema[1] == "jsonschema":
            body = json.loads(schema[2])
            assert body.get("properties"), topic
            jsonschema.Draft202012Validator(body).validate(data)
    assert emitted["/robots/robot1/task"][0][2] == json.dumps(ROBOT_TASK).encode()
    assert emitted["/supervisor/state"][1]["transitions"] == snap["transitions"]
    assert all("task" not in r for r in emitted["/supervisor/state"][1]["robots"]
               if r["state"] == "offline")  # left out, not null


def test_a_recording_reads_back_in_log_time_order_with_ties_in_the_order_written(tmp_path):
    """read_recording sorts the file's order by log time (a C sort, not the mcap library's heap
    of Python comparisons): the order the library's log-time merge gives, ties in write order."""
    from mcap.reader import make_reader

    path = tmp_path / "order.mcap"
    times = [5, 3, 3, 9, 1, 3, 5, 4, 9, 2] * 30  # out of order, many ties
    with McapRecorder(path, flush_every=0.0) as rec:
        for i, t in enumerate(times):
            rec.sample(f"robot{i % 7}/k", "application/octet-stream", str(i).encode(), t)
    records = read_recording(path)
    with open(path, "rb") as f:
        library = [(c.topic, m.log_time, m.data)
                   for _, c, m in make_reader(f).iter_messages(log_time_order=True)]
    assert [(k, t, p) for k, _, t, p in records] == library
    assert len(records) == len(times) and len({t for _, _, t, _ in records}) > 3


@pytest.mark.parametrize("bus_only", [False, True], ids=["view", "record"])
def test_a_stopped_recorder_records_what_is_still_coming_until_the_clock_is_quiet(
        tmp_path, monkeypatch, node_wall, bus_only):
    """The newcomer's `--no-plots` run (issue 51): the mission runner stops the recorder as soon
    as the simulator has ended; a recorder behind on a busy machine still had the last
    simulated second to take, and closing at once cut the recording short of the mission. Here
    the last second arrives after the stop, over a wall second: it is recorded, the recorder
    still runs, then ends once the clock has been quiet for DRAIN_QUIET. The recorder's clock
    counts wall time on a hand-moved wall (no real wait, and no machine too slow for it)."""
    wall = node_wall
    monkeypatch.setattr(record, "DRAIN_MAX", 1e9)  # the quiet ends it, not the bound
    bus, out, stop, th = started_view(tmp_path, bus_only)
    token = bus.declare_token(f"{CLOCK_SOURCE_TOKEN}/run1")
    for k in range(251):  # 5 simulated seconds before the stop
        bus.publish(CLOCK, Clock(k * 0.02, "run1"))
    stop.set()
    wall.wait_polled(3)  # the stopped recorder asks its clock whether it went quiet: draining
    for k in range(251, 301):  # the last simulated second, still on its way
        wall.t += 0.02
        bus.publish(CLOCK, Clock(k * 0.02, "run1"))
    wall.t += record.DRAIN_QUIET * 0.9
    wall.wait_polled(2)
    assert th.is_alive()  # quiet for less than DRAIN_QUIET: still recording
    wall.t += record.DRAIN_QUIET * 0.2
    th.join(60)
    token.close()
    assert not th.is_alive()
    topics, _, _ = read(out)
    assert max(t for t, _ in topics[CLOCK]) == 6 * S
