"""rmw_zenoh's conventions beyond the wire format, in-process: depth 42 both ways,
action and service tokens in the graph, GIDs derived from tokens as rmw_zenoh derives them, DROP
unless RELIABLE + KEEP_ALL, ROS_DOMAIN_ID and client mode in `mrta ros2`, and `bridge_lost`."""

import pytest
from click.testing import CliRunner

from mrta_supervisor.live.api import resolve_application
from mrta_supervisor.live.state import Supervisor
from mrta_zenoh.cli.main import cli
from mrta_zenoh.ros2 import names
from mrta_zenoh.ros2.attachment import Attachment
from mrta_zenoh.ros2.graph import Ros2Graph
from mrta_zenoh.ros2.names import (BEST_EFFORT, COMMANDS, KEEP_ALL, KEEP_LAST, RELIABLE,
                                   SENSOR_DATA, TRANSIENT_LOCAL, VOLATILE, Qos)
from mrta_zenoh.ros2.node import Ros2Node
from mrta_zenoh.ros2.types import Ros2Types

HASH = "RIHS01_" + "0" * 64


# ------------------------------------------------------------------------------ QoS depth


@pytest.mark.parametrize("qos, text", [
    (Qos(RELIABLE, VOLATILE, KEEP_LAST, 42), "::,:,:,:,,"),
    (Qos(RELIABLE, VOLATILE, KEEP_LAST, 10), "::,10:,:,:,,"),
    (Qos(BEST_EFFORT, TRANSIENT_LOCAL, KEEP_LAST, 1), "2:1:,1:,:,:,,"),
    (Qos(RELIABLE, VOLATILE, KEEP_ALL, 42), "::2,:,:,:,,"),
])
def test_depth_42_is_rmw_zenohs_default_both_ways(qos, text):
    """rmw_zenoh's qos_to_keyexpr leaves a depth of 42 out and reads an empty one as 42."""
    assert qos.encode() == text
    assert Qos.decode(text) == qos


def test_an_empty_depth_reads_as_42_not_0():
    assert Qos.decode("::,:,:,:,,").depth == 42


# ------------------------------------------------------------- actions and services in the graph


def _service(kind, eid, name, ros_type):
    return (f"@ros2_lv/0/z9/1/{eid}/{kind}/%/%/fibonacci_server/{names.mangle(name)}/"
            f"{names.dds_type(ros_type)}/{HASH}/::,:,:,:,,")


def test_action_topics_and_services_are_in_the_graph():
    """An action server as rmw_zenoh declares it: services typed `…::action::dds_::…_SendGoal_`,
    a feedback topic typed `…_FeedbackMessage_`; and a plain service with its client."""
    g = Ros2Graph(0)
    keys = [names.node_token(0, "z9", 1, "/", "fibonacci_server"),
            _service("SS", 2, "/fibonacci/_action/send_goal",
                     "example_interfaces/action/Fibonacci_SendGoal"),
            _service("SS", 3, "/fibonacci/_action/get_result",
                     "example_interfaces/action/Fibonacci_GetResult"),
            names.endpoint_token(0, "z9", 1, 4, "MP", "/", "fibonacci_server",
                                 "/fibonacci/_action/feedback",
                                 "example_interfaces/action/Fibonacci_FeedbackMessage", HASH,
                                 COMMANDS),
            _service("SS", 5, "/add_two_ints", "example_interfaces/srv/AddTwoInts"),
            _service("SC", 6, "/add_two_ints", "example_interfaces/srv/AddTwoInts")]
    for key in keys:
        g.on_token(key, True)
    assert g.invalid == 0
    assert g.topics() == [{"topic": "/fibonacci/_action/feedback",
                           "types": ["example_interfaces/action/Fibonacci_FeedbackMessage"],
                           "publishers": 1, "subscriptions": 0}]
    assert g.services() == [
        {"service": "/add_two_ints", "types": ["example_interfaces/srv/AddTwoInts"],
         "servers": 1, "clients": 1},
        {"service": "/fibonacci/_action/get_result",
         "types": ["example_interfaces/action/Fibonacci_GetResult"], "servers": 1, "clients": 0},
        {"service": "/fibonacci/_action/send_goal",
         "types": ["example_interfaces/action/Fibonacci_SendGoal"], "servers": 1, "clients": 0}]
    assert g.snapshot()["services"] == g.services()
    for key in keys:
        g.on_token(key, False)
    assert g.topics() == [] and g.services() == [] and g.nodes() == []


# ----------------------------------------------------------------------------------- GIDs


def test_the_gid_is_xxh3_128_of_the_token_low_half_first():
    """XXH3-128("") = 99aa06d3014798d8 6001c324468d497f (high, low: the reference vector);
    rmw_zenoh copies low64 then high64, each in the machine's (little-endian) order."""
    assert names.gid_of("") == (bytes.fromhex("6001c324468d497f")[::-1]
                                + bytes.fromhex("99aa06d3014798d8")[::-1])
    token = names.endpoint_token(0, "z1", 1, 2, "MP", "/robot1", "n", "/robot1/odom",
                                 "nav_msgs/msg/Odometry", HASH, SENSOR_DATA)
    assert names.gid_of(token) != names.gid_of(token + "x")
    assert len(names.gid_of(token)) == 16


class _FakeBus:
    """What Ros2Node needs of a ZenohBus, recording what it is asked for."""

    zid = "0123456789abcdef"

    def __init__(self):
        self.tokens, self.publishers = [], []

    def declare_absolute_token(self, key):
        self.tokens.append(key)
        return _Closable()

    def declare_attached_publisher(self, key, *, lossy):
        pub = _Pub(key, lossy)
        self.publishers.append(pub)
        return pub


class _Closable:
    def close(self):
        pass


class _Pub(_Closable):
    def __init__(self, key, lossy):
        self.key, self.lossy, self.sent = key, lossy, []

    def put(self, payload, attachment):
        self.sent.append(attachment)


@pytest.fixture(scope="module")
def types():
    return Ros2Types("jazzy")


def test_samples_carry_the_gid_of_their_publishers_token(types):
    bus = _FakeBus()
    node = Ros2Node(bus, types, name="n", namespace="/robot1")
    pub = node.publisher("cmd_vel", "geometry_msgs/msg/Twist", COMMANDS)
    pub.publish_cdr(b"\x00\x01\x00\x00" + b"\x00" * 48)
    token = next(t for t in bus.tokens if "/MP/" in t)
    assert Attachment.unpack(bus.publishers[0].sent[0]).gid == names.gid_of(token)


@pytest.mark.parametrize("qos, lossy", [
    (Qos(RELIABLE, VOLATILE, KEEP_LAST, 10), True),   # DROP, as rmw_zenoh: not BLOCK
    (Qos(BEST_EFFORT, VOLATILE, KEEP_LAST, 5), True),
    (Qos(BEST_EFFORT, VOLATILE, KEEP_ALL, 5), True),
    (Qos(RELIABLE, VOLATILE, KEEP_ALL, 5), False),  # BLOCK only here
])
def test_publishers_drop_unless_reliable_keep_all(types, qos, lossy):
    bus = _FakeBus()
    Ros2Node(bus, types, name="n").publisher("t", "geometry_msgs/msg/Twist", qos)
    assert bus.publishers[0].lossy is lossy


# ------------------------------------------------------------------------------- the CLI


@pytest.fixture
def captured(monkeypatch):
    """`mrta ros2 bridge | graph` with the work replaced by a recorder of its arguments."""
    seen = {}
    monkeypatch.setattr("mrta_zenoh.cli.ros2.run_bridge", lambda **kw: seen.update(kw))

    def graph(**kw):
        seen.update(kw)
        return {"domain": kw["domain"], "nodes": [], "topics": [], "services": []}

    monkeypatch.setattr("mrta_zenoh.cli.ros2.read_graph", graph)
    return seen


@pytest.mark.parametrize("args", [["ros2", "bridge", "--robot", "robot1"], ["ros2", "graph"]])
def test_ros_domain_id_is_the_default_domain(captured, monkeypatch, args):
    monkeypatch.setenv("ROS_DOMAIN_ID", "5")
    res = CliRunner().invoke(cli, args)
    assert res.exit_code == 0, res.output
    assert captured["domain"] == 5
    res = CliRunner().invoke(cli, [*args, "--domain", "7"])
    assert captured["domain"] == 7


def test_a_bad_ros_domain_id_is_a_usage_error(captured, monkeypatch):
    monkeypatch.setenv("ROS_DOMAIN_ID", "300")
    res = CliRunner().invoke(cli, ["ros2", "graph"])
    assert res.exit_code == 2 and "ROS_DOMAIN_ID" in res.output


@pytest.mark.parametrize("args", [["ros2", "bridge", "--robot", "robot1"], ["ros2", "graph"]])
def test_connect_without_mode_means_client(captured, monkeypatch, args):
    monkeypatch.delenv("ROS_DOMAIN_ID", raising=False)
    end = "tcp/127.0.0.1:17447"
    assert CliRunner().invoke(cli, [*args, "--connect", end]).exit_code == 0
    assert captured["bus_options"].mode == "client"
    assert CliRunner().invoke(cli, [*args, "--connect", end, "--mode", "peer"]).exit_code == 0
    assert captured["bus_options"].mode == "peer"
    assert CliRunner().invoke(cli, args).exit_code == 0  # zero-config: our rendezvous, as peer
    assert captured["bus_options"].mode == "peer"


def test_namespace_is_the_bus_namespace_and_ros_namespace_the_robots(captured):
    res = CliRunner().invoke(cli, ["ros2", "bridge", "--robot", "robot1", "--namespace", "team_a",
                                   "--ros-namespace", "/pioneer"])
    assert res.exit_code == 0, res.output
    assert captured["bus_options"].namespace == "team_a"
    assert captured["links"][0].namespace == "/pioneer"


# ------------------------------------------------------------------------------ bridge_lost


def test_a_robot_whose_bridge_died_is_offline_with_bridge_lost():
    app, arch = resolve_application("patrol")
    sup = Supervisor(arch, app, 0.0)
    driver = names.node_token(0, "z1", 1, "/robot2", "pioneer_driver")
    sup.on_liveliness("robot2/alliance/agent", True, 1.0)
    sup.on_bridge_token("@mrta/ros2_bridge/robot2", True, 1.5)
    sup.on_ros2_token(driver, True, 2.0)

    def state(t):
        snap = sup.snapshot(t)
        return ({r["id"]: r["state"] for r in snap["robots"]}["robot2"],
                [(a["kind"], a["subject"]) for a in snap["alarms"]])

    assert state(2.0) == ("idle", [])
    sup.on_bridge_token("@mrta/ros2_bridge/robot2", False, 3.0)  # the bridge died
    assert state(3.0) == ("offline", [("bridge_lost", "robot2")])
    sup.on_bridge_token("@mrta/ros2_bridge/robot2", True, 4.0)  # a bridge is back
    assert state(4.0) == ("idle", [])
    sup.on_bridge_token("@mrta/ros2_bridge/robot2", False, 5.0)
    sup.on_ros2_token(driver, False, 6.0)  # the ROS 2 side is gone too: nothing left to drive
    assert state(6.0) == ("idle", [])


def test_a_node_in_an_unbridged_namespace_raises_no_bridge_lost():
    app, arch = resolve_application("patrol")
    sup = Supervisor(arch, app, 0.0)
    sup.on_liveliness("robot2/alliance/agent", True, 1.0)
    sup.on_ros2_token(names.node_token(0, "z1", 1, "/robot2", "forged"), True, 2.0)
    snap = sup.snapshot(2.0)
    assert {r["id"]: r["state"] for r in snap["robots"]}["robot2"] == "idle"
    assert snap["alarms"] == []


def test_ros_domain_id_is_every_ros2_options_default(tmp_path, monkeypatch):
    """`ROS_DOMAIN_ID` is what a ROS 2 user sets once: the simulator's stand-in and the
    secured fleet's rules follow it too, not only the bridge and the graph."""
    import json

    from click.testing import CliRunner

    from mrta_zenoh.cli.main import cli
    monkeypatch.setenv("ROS_DOMAIN_ID", "5")
    result = CliRunner().invoke(cli, ["secure", "init", str(tmp_path / "f"), "--robot", "robot1"])
    assert result.exit_code == 0, result.output
    router = json.loads((tmp_path / "f" / "router.json5").read_text())
    keys = {k for r in router["access_control"]["rules"] for k in r["key_exprs"]}
    assert "5/robot1/**" in keys and "0/robot1/**" not in keys
    assert "ROS_DOMAIN_ID" in CliRunner().invoke(cli, ["sim", "--help"]).output
