"""The ROS 2 bridge's limits, on an in-process bus with a stand-in for
rmw_zenoh's side (deterministic, no Zenoh): non-finite values are dropped and counted, an
oversized sample is dropped before it is decoded, and `--mirror` makes a bounded number of ROS 2
topics from the bridged robots' keys only."""

import json
import math
import signal

import pytest

from mrta_zenoh.bus.inproc import InProcBus
from mrta_zenoh.messages import Header, Odometry, Point2D, PointCloud, Pose2D, Twist
from mrta_zenoh.ros2 import bridge as bridge_module
from mrta_zenoh.ros2.attachment import Stamper
from mrta_zenoh.ros2.bridge import (MAX_MIRRORED, MIRROR_IDLE, ODOM_MAX_BYTES, SONAR_MAX_BYTES,
                                    Bridge, RobotLink)
from mrta_zenoh.ros2.mirror import Mirror
from mrta_zenoh.ros2.names import COMMANDS
from mrta_zenoh.ros2.types import ODOMETRY, SONAR_TYPES, TWIST, Ros2Types
from mrta_zenoh.keys import matches

TYPES = Ros2Types("jazzy")


class Handle:
    def __init__(self, remove):
        self._remove = remove

    def close(self) -> None:
        self._remove()


class Ros2SideBus(InProcBus):
    """Our in-process bus plus what Ros2Node needs of a ZenohBus: attached publishers and
    subscriptions on absolute keys, and absolute liveliness tokens — recorded, so a test can
    play a ROS 2 driver (`ros_put`) and count the bridge's ROS 2 topics (`ros2_tokens`)."""

    zid = "0123abcd"

    def __init__(self):
        super().__init__()
        self.attached_subs: list[tuple[str, object]] = []
        self.ros2_tokens: set[str] = set()
        self.ros_published: list[tuple[str, bytes]] = []

    def declare_attached_publisher(self, key: str, *, lossy: bool):
        bus = self

        class Pub:
            def put(self, payload, attachment):
                bus.ros_published.append((key, payload))

            def close(self):
                pass
        return Pub()

    def subscribe_attached(self, key_expr, handler):
        entry = (key_expr, handler)
        self.attached_subs.append(entry)
        return Handle(lambda: self.attached_subs.remove(entry))

    def declare_absolute_token(self, key):
        self.ros2_tokens.add(key)
        return Handle(lambda: self.ros2_tokens.discard(key))

    def ros_put(self, key: str, payload: bytes) -> None:
        att = Stamper().next(1_700_000_000 * 10**9)
        for expr, handler in list(self.attached_subs):
            if matches(expr, key):
                handler(key, payload, att)

    def topics(self) -> set[str]:
        """Topics of the bridge's publishers, from their liveliness tokens."""
        return {t.split("/")[9] for t in self.ros2_tokens if t.split("/")[5] == "MP"}


@pytest.fixture
def bus():
    b = Ros2SideBus()
    yield b
    b.close()


def received(bus, key):
    got = []
    bus.subscribe(key, got.append)
    return got


def odom_cdr(x: float, theta: float = 0.0) -> bytes:
    return TYPES.serialize(TYPES.odometry_to_ros(
        Odometry(Header("odom", 5.0, 0), Pose2D(x, 1.0, theta), Twist(0.1, 0.0))), ODOMETRY)


def sonar_cdr(n: int) -> bytes:
    pts = tuple(Point2D(math.cos(i), math.sin(i)) for i in range(n))
    return TYPES.serialize(TYPES.sonar_to_ros(PointCloud(Header("s", 5.0, 0), pts), "pointcloud"),
                           SONAR_TYPES["pointcloud"])


def key_of(topic: str, ros_type: str) -> str:
    from mrta_zenoh.ros2.names import topic_key
    return topic_key(0, topic, ros_type, TYPES.hash(ros_type))


def test_non_finite_odometry_is_dropped_and_counted_never_forwarded(bus):
    got = received(bus, "robot1/odom")
    with Bridge(bus, [RobotLink.make("robot1")]) as br:
        key = key_of("/robot1/odom", ODOMETRY)
        for bad in (odom_cdr(math.nan), odom_cdr(math.inf), odom_cdr(1.0, theta=math.nan)):
            bus.ros_put(key, bad)
        bus.ros_put(key, odom_cdr(2.0))
        assert [s.message.pose.x for s in got] == [2.0]   # only the finite one went on
        assert br.stats.dropped == {"robot1/odom (non-finite)": 3}
        assert br.stats.from_ros == {"robot1/odom": 1}


def test_an_oversized_sample_is_dropped_before_it_is_decoded(bus, monkeypatch):
    got = received(bus, "robot1/sonar")
    with Bridge(bus, [RobotLink.make("robot1")]) as br:
        decoded = []
        real = br.types.deserialize
        monkeypatch.setattr(br.types, "deserialize",
                            lambda data, t: decoded.append(len(data)) or real(data, t))
        key = key_of("/robot1/sonar", SONAR_TYPES["pointcloud"])
        big = sonar_cdr(SONAR_MAX_BYTES // 12 + 10)
        assert len(big) > SONAR_MAX_BYTES
        bus.ros_put(key, big)
        bus.ros_put(key, sonar_cdr(16))
        assert decoded == [len(sonar_cdr(16))]         # the big one was never decoded
        assert [len(s.message.points) for s in got] == [16]
        counts = br.subscription_counts()["/robot1/sonar"]
        assert counts["oversized"] == 1 and counts["received"] == 1
        # the odometry cap: far above a real message, far below an attack
        assert len(odom_cdr(1.0)) < ODOM_MAX_BYTES // 16
        bus.ros_put(key_of("/robot1/odom", ODOMETRY), odom_cdr(1.0) + b"\0" * ODOM_MAX_BYTES)
        assert br.subscription_counts()["/robot1/odom"]["oversized"] == 1


def test_the_sonar_cap_is_an_option(bus):
    got = received(bus, "robot1/sonar")
    with Bridge(bus, [RobotLink.make("robot1")], max_sonar_bytes=200) as br:
        bus.ros_put(key_of("/robot1/sonar", SONAR_TYPES["pointcloud"]), sonar_cdr(16))  # 224 B
        assert got == [] and br.subscription_counts()["/robot1/sonar"]["oversized"] == 1


class Clock:
    def __init__(self):
        self.t = 0.0

    def __call__(self):
        return self.t


@pytest.fixture
def status_mirror(monkeypatch):
    """A mirror of our own: robotN/status/* (Twist) → the ROS 2 topic <ns>/status/<x>."""
    m = Mirror("status/*", Twist, TWIST, COMMANDS, lambda types, msg: types.twist_to_ros(msg))
    monkeypatch.setattr(bridge_module, "registered_mirrors", lambda: [m])
    return m


def test_mirror_makes_a_bounded_number_of_topics_from_invented_keys(bus, status_mirror):
    clock = Clock()
    with Bridge(bus, [RobotLink.make("robot1")], mirror=True, monotonic=clock) as br:
        base = len(bus.topics())                           # cmd_vel
        for i in range(MAX_MIRRORED * 3):
            bus.publish(f"robot1/status/k{i}", Twist(1.0, 0.0))
        assert len(bus.topics()) - base == MAX_MIRRORED   # before: one per key, 2,920 → 2,923
        assert br.stats.dropped == {"robot1/status/* (mirror limit)": 2 * MAX_MIRRORED}
        # another robot's keys are never mirrored by robot1's bridge
        bus.publish("robot2/status/x", Twist(1.0, 0.0))
        assert not any("robot2" in t for t in bus.topics())
        # a key that keeps publishing keeps its topic; a new one takes a silent one's place
        clock.t = MIRROR_IDLE / 2
        bus.publish("robot1/status/k0", Twist(2.0, 0.0))
        clock.t = MIRROR_IDLE + 1
        bus.publish("robot1/status/wander", Twist(3.0, 0.0))
        topics = bus.topics()
        assert "%robot1%status%wander" in topics and "%robot1%status%k0" in topics
        assert "%robot1%status%k1" not in topics           # the one silent longest gave way
        assert len(topics) - base == MAX_MIRRORED
        # a key that is not a ROS name is counted under the key expression, not per key
        for i in range(50):
            bus.publish(f"robot1/status/bad-{i}", Twist(1.0, 0.0))
        assert br.stats.dropped["robot1/status/* (not a ROS name)"] == 50
        assert len(br.stats.dropped) == 2


def rss_mb(pid: int) -> float:
    with open(f"/proc/{pid}/status") as f:
        return next(int(line.split()[1]) for line in f if line.startswith("VmRSS")) / 1024


@pytest.mark.slow
@pytest.mark.multiprocess
@pytest.mark.timeout(240)
def test_a_flood_of_huge_clouds_neither_grows_the_bridge_nor_stops_its_sonar(children, tokens):
    """Four 1M-point clouds (12 MB each), twice a second, at a real bridge process: dropped
    undecoded (before: a core at 100 % and 58 → 409 MB); the small clouds after them still
    arrive on our key."""
    bridge = children.mrta("ros2", "bridge", "--robot", "robot1", name="bridge")
    tokens.wait("@mrta/ros2_bridge/robot1", 60, bridge)
    before = rss_mb(bridge.proc.pid)
    echo = children.mrta("echo", "robot1/sonar", "--json", name="echo")
    tokens.subscribed("robot1/sonar", 30, echo)
    flood = children.python("ros2_flood.py", "robot1", "1000000", "4", name="flood")
    flood.wait_json(lambda o: o.get("big") == 4, 90)
    small = echo.wait_json(lambda o: len(o["message"]["points"]) == 16, 60)
    assert small["message"]["header"]["stamp"] > 100       # one sent after the big ones
    grown = rss_mb(bridge.proc.pid) - before
    flood.stop()
    bridge.signal(signal.SIGTERM)
    assert bridge.wait(30) == 0
    done = next(line for line in bridge.stderr if "done:" in line)
    assert "'oversized': 4" in done
    assert all(len(json.loads(x)["message"]["points"]) == 16
               for x in echo.stdout if x.startswith("{"))
    assert grown < 60, f"the bridge grew by {grown:.0f} MB"
