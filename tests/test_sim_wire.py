"""The simulator's sensor samples written from its arrays (simulator/wire.py) are the wire
contract: byte for byte what `codec.encode` gives for the message objects, on the same keys, in
the same order, with the same encodings — for random states (signed zeros, huge and tiny floats,
ids of every length, no sonar and many), for a real simulation on the in-process bus against the
per-robot message-object path kept here as the reference, and through a real Zenoh session's batch."""

from __future__ import annotations

import math
import threading
import time

import msgspec
import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings, strategies as st

from mrta_zenoh import codec, keys
from mrta_zenoh.bus.inproc import InProcBus
from mrta_zenoh.messages import Header, Odometry, Point2D, PointCloud, Pose2D, Twist
from mrta_simulator.engine import Simulation
from mrta_simulator.messages import Bumper
from mrta_simulator.node import SimNode, bumper_key
from mrta_simulator.robot_model import RobotModel
from mrta_simulator.wire import SensorWire, msgpack_ints, sample_messages
from mrta_simulator.world import Pose, World

SETTINGS = settings(max_examples=60, derandomize=True, deadline=None,
                    suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])

FLOATS = st.one_of(
    st.floats(allow_nan=False, allow_infinity=False),
    st.sampled_from([0.0, -0.0, 5e-324, -5e-324, 2.2250738585072014e-308, 1.7976931348623157e308,
                     -1.7976931348623157e308, 1e-300, 0.1, 5.0, -math.pi]))
INTS = st.one_of(st.integers(0, 300), st.integers(-(1 << 63), (1 << 63) - 1),
                 st.sampled_from([127, 128, 255, 256, 65535, 65536, (1 << 32) - 1, 1 << 32,
                                  -1, -32, -33, -128, -129, -32768, -32769, -(1 << 31),
                                  -(1 << 31) - 1]))
ID_CHARS = st.characters(min_codepoint=0x21, max_codepoint=0x2FF,
                         blacklist_characters="/*$#?@")


def object_messages(rid, t, points, odom, twist, pose, vel, stalled, contact, collisions):
    """A robot's samples as message objects: the straightforward way, the wire's reference."""
    return (PointCloud(Header(f"{rid}/sonar", t, 0), tuple(Point2D(x, y) for x, y in points)),
            Odometry(Header(f"{rid}/odom", t, 0), Pose2D(*odom), Twist(*twist)),
            Odometry(Header("world", t, 0), Pose2D(*pose), Twist(*vel)),
            Bumper(Header(rid, t, 0), stalled, contact, collisions))


def object_publish_all(node: SimNode) -> None:
    """The message-object path: message objects per robot, Bus.publish each."""
    sim = node.sim
    t = sim.time
    reading = sim.sonar()
    pts = reading.points.tolist()
    pose, odom, twist = sim.pose.tolist(), sim.odom.tolist(), sim.odom_twist.tolist()
    vel = sim.vel.tolist()
    stalled, contacts = sim.stalled.tolist(), (sim.contacts > 0).tolist()
    collisions = sim.collisions.tolist()
    for i, rid in enumerate(sim.ids):
        cloud, odometry, truth, bump = object_messages(rid, t, pts[i], odom[i], twist[i], pose[i],
                                                    vel[i], stalled[i], contacts[i],
                                                    collisions[i])
        if rid in node._ros2_ids:
            node.ros2.publish(rid, odometry, cloud)
        else:
            node.bus.publish(keys.sonar(rid), cloud, lossy=True)
            node.bus.publish(keys.odom(rid), odometry, lossy=True)
        node.bus.publish(keys.ground_truth(rid), truth, lossy=True)
        node.bus.publish(bumper_key(rid), bump, lossy=True)


@st.composite
def states(draw):
    """Robot ids (distinct, 1–300 characters), sonar points per robot (none to many), and two
    successive periods of every array SensorWire reads."""
    ids = draw(st.lists(st.text(ID_CHARS, min_size=1, max_size=40) |
                        st.text(ID_CHARS, min_size=250, max_size=300),
                        min_size=1, max_size=6, unique=True))
    k = draw(st.sampled_from([0, 1, 8, 16, 17]))
    n = len(ids)

    def arr(*shape):
        size = int(np.prod(shape))
        return np.array(draw(st.lists(FLOATS, min_size=size, max_size=size)),
                        dtype=float).reshape(shape)

    periods = []
    for _ in range(2):
        periods.append(dict(
            t=draw(FLOATS), points=arr(n, k, 2), odom=arr(n, 3), odom_twist=arr(n, 2),
            pose=arr(n, 3), vel=arr(n, 2),
            stalled=np.array(draw(st.lists(st.booleans(), min_size=n, max_size=n)), dtype=bool),
            contact=np.array(draw(st.lists(st.booleans(), min_size=n, max_size=n)), dtype=bool),
            collisions=np.array(draw(st.lists(INTS, min_size=n, max_size=n)), dtype=np.int64)))
    omit = draw(st.sets(st.sampled_from(ids), max_size=2))
    return ids, k, omit, periods


@pytest.mark.slow
@SETTINGS
@given(states())
def test_fast_bytes_are_codec_encode_of_the_messages(state):
    ids, k, omit, periods = state
    wire = SensorWire(ids, k, omit=omit)
    for p in periods:  # the same encoder twice: nothing of one period may leak into the next
        got = wire.encode(**p)
        want_keys, want_encs, want = [], [], []
        for i, rid in enumerate(ids):
            msgs = object_messages(rid, p["t"], p["points"][i].tolist(), p["odom"][i].tolist(),
                                p["odom_twist"][i].tolist(), p["pose"][i].tolist(),
                                p["vel"][i].tolist(), bool(p["stalled"][i]),
                                bool(p["contact"][i]), int(p["collisions"][i]))
            assert msgs == sample_messages(rid, p["t"], p["points"][i].tolist(),
                                           p["odom"][i].tolist(), p["odom_twist"][i].tolist(),
                                           p["pose"][i].tolist(), p["vel"][i].tolist(),
                                           bool(p["stalled"][i]), bool(p["contact"][i]),
                                           int(p["collisions"][i]))
            for kind, (key, msg) in enumerate(zip(
                    (keys.sonar(rid), keys.odom(rid), keys.ground_truth(rid), bumper_key(rid)),
                    msgs)):
                if rid in omit and kind < 2:
                    continue
                want_keys.append(key)
                want_encs.append(codec.encoding_for(msg.TYPE_NAME))
                want.append((msg, codec.encode(msg)))
        assert wire.keys == want_keys
        assert wire.encodings == want_encs
        assert list(got) == [b for _, b in want]
        for payload, (msg, _), enc in zip(got, want, want_encs):
            # strict decoding (finite floats, exact fields) gives the values back
            back = codec.decode(codec.type_from_encoding(enc), payload)
            assert back == msg
            assert msgspec.msgpack.decode(payload) == msgspec.msgpack.decode(codec.encode(msg))


@pytest.mark.parametrize("value", [0, 1, 127, 128, 255, 256, 65535, 65536, (1 << 32) - 1,
                                   1 << 32, (1 << 63) - 1, -1, -32, -33, -128, -129, -32768,
                                   -32769, -(1 << 31), -(1 << 31) - 1, -(1 << 63)])
def test_msgpack_ints_are_msgspec_ints(value):
    out = np.zeros((2, 9), dtype=np.uint8)
    width = msgpack_ints(np.array([value, 5], dtype=np.int64), out)
    assert bytes(out[0, :width[0]]) == msgspec.msgpack.encode(value)
    assert bytes(out[1, :width[1]]) == b"\x05"


BOX = World("box", np.array([[-3, -3, 3, -3], [3, -3, 3, 3], [3, 3, -3, 3], [-3, 3, -3, -3]],
                            dtype=float))


def crowded(model: RobotModel | None = None) -> Simulation:
    """Robots with ids of several lengths, some driving into the walls and into each other (so
    contacts, stalls and collision counts change during the run)."""
    poses = {"r1": Pose(2.5, 0, 0), "robot22": Pose(-2.5, 0, math.pi),
             "a-much-longer-robot-name-than-32-chars": Pose(0, 0.1, 0.0),
             "b": Pose(0.6, 0, math.pi), "robot7": Pose(0, -2.4, -math.pi / 2)}
    sim = Simulation(BOX, poses, model=model, seed=7)
    sim.cmd[:] = [[0.6, 0.0], [0.6, 0.1], [0.5, 0.0], [0.5, -0.2], [0.4, 0.0]]
    sim.cmd_time[:] = 1e12  # never stale
    return sim


class FakeRos2Driver:
    """What SimNode needs of simulator/ros2.Ros2Driver, recording what it is handed."""

    def __init__(self, robots):
        self.nodes = {r: None for r in robots}
        self.sent = []

    def publish(self, rid, odom, sonar):
        self.sent.append((rid, odom, sonar))

    def close(self):
        pass


def record(publish_all, ros2=(), rear_sonars=False):
    """Every sample a SimNode sends on the in-process bus in 1.2 simulated seconds, as (key,
    encoding, payload), and what its ROS 2 driver got; `publish_all` replaces the node's own
    when given."""
    bus = InProcBus()
    got = []
    sub = bus.subscribe_raw("**", lambda s: got.append((s.key, s.encoding, s.payload)))
    drivers = []

    def make_driver(command):
        drivers.append(FakeRos2Driver(ros2))
        return drivers[0]

    node = SimNode(crowded(RobotModel(rear_sonars=rear_sonars)), bus, speed=0.0,
                   ros2=make_driver if ros2 else None)
    if publish_all is not None:
        node.publish_all = lambda: publish_all(node)
    node.run(threading.Event(), duration=1.2)
    collisions = node.sim.collisions.tolist()
    node.close()
    sub.close()
    bus.close()
    return got, (drivers[0].sent if drivers else []), collisions


def bumpers_on_change(samples):
    """The message-object path's samples with the bumper rule applied (simulator/node.py, BUMPER_EVERY):
    a robot's bumper goes out when (stalled, contact, collisions) differs from the last one it
    sent, and every robot's at each whole simulated second. Worked out here from the decoded
    samples, independently of the node's arrays."""
    kept, last = [], {}
    for key, enc, payload in samples:
        if key.endswith("/bumper"):
            msg = msgspec.msgpack.decode(payload)
            state = (msg["stalled"], msg["contact"], msg["collisions"])
            stamp = msg["header"]["stamp"]
            whole = abs(stamp - round(stamp)) < 1e-9
            if not whole and last.get(key) == state:
                continue
            last[key] = state
        kept.append((key, enc, payload))
    return kept


@pytest.mark.parametrize("ros2, rear", [((), False), (("robot22",), False), ((), True)])
def test_simnode_sends_what_the_message_object_path_sends(ros2, rear):
    new, new_ros2, collisions = record(None, ros2, rear)
    every, old_ros2, _ = record(object_publish_all, ros2, rear)
    old = bumpers_on_change(every)
    assert any(c > 0 for c in collisions)  # the run did exercise contacts
    assert len(new) == len(old) > 0
    assert new == old
    bumps = [k for k, _, _ in new if k.endswith("/bumper")]
    assert 0 < len(bumps) < len([k for k, _, _ in every if k.endswith("/bumper")])
    assert new_ros2 == old_ros2
    sensor_keys = {k for k, _, _ in new if k.endswith(("/sonar", "/odom"))}
    assert not any(k.startswith(r + "/") for r in ros2 for k in sensor_keys)


def test_a_batch_on_the_inproc_bus_counts_and_delivers_like_publish():
    bus = InProcBus()
    got = []
    bus.subscribe_raw("a/**", lambda s: got.append((s.key, s.encoding, s.payload)))
    counts = bus.enable_counting()
    enc = codec.encoding_for(Twist.TYPE_NAME)
    batch = bus.declare_batch(["a/x", "a/y", "a/x"], [enc] * 3, lossy=True)
    payloads = [codec.encode(Twist(float(i), 0.0)) for i in range(3)]
    batch.publish(payloads)
    assert got == [("a/x", enc, payloads[0]), ("a/y", enc, payloads[1]),
                   ("a/x", enc, payloads[2])]
    assert counts.sent == {"a/x": 2, "a/y": 1}
    got.clear()
    batch.publish(payloads, rows=[1, 2])  # only those keys, payloads still one per key
    assert got == [("a/y", enc, payloads[1]), ("a/x", enc, payloads[2])]
    assert counts.sent == {"a/x": 3, "a/y": 2}
    batch.publish(payloads, rows=[])
    assert counts.sent == {"a/x": 3, "a/y": 2}
    with pytest.raises(ValueError):
        batch.publish(payloads, rows=[3])
    with pytest.raises(ValueError):
        batch.publish(payloads[:2])
    with pytest.raises(ValueError):
        bus.declare_batch(["a/x"], [])
    bus.close()


@pytest.mark.slow
@pytest.mark.multiprocess
def test_a_batch_on_zenoh_arrives_with_each_keys_encoding_and_is_counted():
    from mrta_zenoh.bus import BusOptions, open_bus
    from mrta_zenoh.errors import MrtaRuntimeError
    from tests.harness.helpers import free_port

    end = f"tcp/127.0.0.1:{free_port()}"
    odom_enc, bump_enc = (codec.encoding_for(Odometry.TYPE_NAME),
                          codec.encoding_for(Bumper.TYPE_NAME))
    with open_bus(BusOptions(listen=[end])) as a, open_bus(BusOptions(connect=[end])) as b:
        got, lock = [], threading.Lock()

        def on(s):
            with lock:
                got.append((s.key, s.encoding, s.payload))

        sub = b.subscribe_raw("w/**", on)
        # w/0 already has a publisher without a default encoding: that batch names it per put;
        # w/1 and w/2 get publishers declared with their encodings
        a.publish("w/0", Twist(1.0, 2.0), lossy=True)
        fresh = a.declare_batch(["w/1", "w/2"], [odom_enc, bump_enc], lossy=True)
        known = a.declare_batch(["w/0"], [bump_enc], lossy=True)
        counts = a.enable_counting()
        msgs = [Odometry(Header("w", 1.0, 0), Pose2D(1, 2, 3), Twist(4, 5)),
                Bumper(Header("w", 1.0, 0), True, False, 300)]
        payloads = [codec.encode(m) for m in msgs]
        deadline = time.monotonic() + 20
        while time.monotonic() < deadline:  # until the subscription is matched
            fresh.publish(payloads)
            known.publish(payloads[1:])
            time.sleep(0.05)
            with lock:
                if {k for k, e, _ in got if k != "w/0" or e == bump_enc} == {"w/0", "w/1", "w/2"}:
                    break
        with lock:
            seen = {(k, e, p) for k, e, p in got if k != "w/0" or e == bump_enc}
        assert seen == {("w/1", odom_enc, payloads[0]), ("w/2", bump_enc, payloads[1]),
                        ("w/0", bump_enc, payloads[1])}
        assert counts.sent["w/1"] == counts.sent["w/2"] == counts.sent["w/0"] >= 1
        # rows: only w/2 goes out (and is counted), through both kinds of batch
        sent = dict(counts.sent)
        with lock:
            got.clear()
        fresh.publish(payloads, rows=[1])
        known.publish(payloads[1:], rows=[])
        assert counts.sent["w/2"] == sent["w/2"] + 1
        assert counts.sent["w/1"] == sent["w/1"] and counts.sent["w/0"] == sent["w/0"]
        deadline = time.monotonic() + 20
        while time.monotonic() < deadline:
            with lock:
                if got:
                    break
            time.sleep(0.02)
        time.sleep(0.2)
        with lock:
            assert got == [("w/2", bump_enc, payloads[1])]
        sub.close()
    with pytest.raises(MrtaRuntimeError):
        fresh.publish(payloads)


def _clock_stamps(barrier_for=None, participant_every=None, duration=1.0):
    """Stamps of the clock samples a SimNode sends in `duration` simulated seconds: free
    running, or in lockstep with a participant that is due every `participant_every` s."""
    from mrta_zenoh.bus.inproc import InProcNetwork
    from mrta_zenoh.clock import run_id
    from mrta_zenoh.lockstep.barrier import Barrier
    from mrta_zenoh.lockstep.participant import LockstepClock
    from mrta_zenoh.messages import Clock

    net = InProcNetwork()
    bus = InProcBus(net)
    stamps = []
    sub = bus.subscribe(keys.CLOCK, lambda s: stamps.append(s.message.stamp), msg_type=Clock)
    stop = threading.Event()
    node = SimNode(crowded(), bus, speed=0.0, publish_sensors=False)
    barrier = stack = None
    threads = []
    if barrier_for is not None:
        run = run_id(0.0)
        barrier = Barrier(bus, run, 30.0)
        source = bus.declare_token(f"{keys.CLOCK_SOURCE_TOKEN}/{run}")
        agent_bus = InProcBus(net)
        clock = LockstepClock("robot1")
        stack = clock.join(agent_bus)

        def loop():
            clock.started.wait(10)
            t = clock.now()
            while not stop.is_set():
                t = round(t + participant_every, 6)
                if not clock.sleep_until(t, stop):
                    return

        threads.append(threading.Thread(target=loop, daemon=True))
        threads[0].start()
        barrier.settle(quiet=0.05, limit=1.0)
    try:
        node.run(stop, duration=duration, barrier=barrier)
    finally:
        stop.set()
        for t in threads:
            t.join(5)
        if stack is not None:
            stack.close()
            barrier.close()
            source.close()
        node.close()
        sub.close()
    return [round(s, 6) for s in stamps]


def test_a_lockstep_simulator_sends_the_clock_once_a_sensor_period_and_at_its_stops():
    """In lockstep the clock is for observers (participants move with steps): it goes out at
    each sensor period, wherever the barrier stops — here a participant due every 0.06 s — and
    at the physics step after each stop, not at every physics step, as a free-running
    simulator sends it."""
    free = _clock_stamps()
    assert free == [round(0.02 * k, 6) for k in range(0, 51)]
    locked = _clock_stamps(barrier_for="robot1", participant_every=0.06)
    stops = {round(0.06 * k, 6) for k in range(0, 17)}  # 0: the run's first instant
    after = {round(s + 0.02, 6) for s in stops}
    periods = {round(0.1 * k, 6) for k in range(1, 11)}
    assert set(locked) - {0.0} == {s for s in periods | stops | after if 0 < s <= 1.0 + 1e-9}
    assert len(locked) < len(free) * 0.8
