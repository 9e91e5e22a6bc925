"""Our bridge against an independent ROS 2 peer — zenoh-ros2-sdk (ROBOTIS), which speaks
rmw_zenoh from plain Python — over a real Zenoh router on a free loopback port, every party a
separate process. The SDK is lenient about attachments, so their strict format is asserted on
the wire here (tests/procs/ros2_probe.py)."""

import json
import signal
import struct

import pytest

from tests.harness.ros2_msgs import write_msgs

pytestmark = pytest.mark.multiprocess

ROBOT = "robot1"


@pytest.fixture(scope="module")
def msgs(tmp_path_factory):
    return write_msgs(tmp_path_factory.mktemp("ros2_msgs"), [
        "geometry_msgs/msg/Twist", "nav_msgs/msg/Odometry", "sensor_msgs/msg/PointCloud"])


@pytest.fixture
def network(children, tokens):
    """A router on the test's rendezvous port (the SDK connects to it) and our bridge."""
    router = children.mrta("router", name="router")
    router.wait_stderr(lambda line: "router listening" in line, 30)  # a router has no token
    bridge = children.mrta("ros2", "bridge", "--robot", ROBOT, name="bridge")
    tokens.wait(f"@mrta/ros2_bridge/{ROBOT}", 30, bridge)  # declared once it bridges
    return children, bridge


def sdk(children, msgs, *args):
    return children.python("sdk_peer.py", str(msgs), str(children.port), *args,
                           name=f"sdk {args[0]}")


@pytest.mark.slow
def test_our_twist_reaches_the_sdk_with_strict_attachments(network, msgs):
    children, bridge = network
    listener = sdk(children, msgs, "sub-twist", f"/{ROBOT}/cmd_vel")
    listener.wait_json(lambda o: o.get("ready"), 60)
    wire = children.python("ros2_probe.py", "attachments", f"0/{ROBOT}/cmd_vel/**", name="wire")
    wire.wait_json(lambda o: o.get("ready"), 30)
    # sent at 10 Hz until stopped: whichever arrive first, five in a row must be intact
    cmd = children.python("ros2_probe.py", "cmd", ROBOT, "600", name="cmd")
    first = listener.wait_json(lambda o: "linear" in o, 60)
    i0 = round(first["linear"] / 0.1)
    got = [first] + [listener.wait_json(lambda o, i=i: "linear" in o
                                        and abs(o["linear"] - 0.1 * i) < 1e-9, 30)
                     for i in range(i0 + 1, i0 + 5)]
    assert [g["angular"] for g in got] == [-0.2] * 5
    seen = [wire.wait_json(lambda o: o.get("attachment"), 30)]
    n0 = struct.unpack_from("<q", bytes.fromhex(seen[0]["attachment"]))[0]
    seen += [wire.wait_json(lambda o, n=n: o.get("attachment") and
                            struct.unpack_from("<q", bytes.fromhex(o["attachment"]))[0] == n, 30)
             for n in range(n0 + 1, n0 + 5)]
    cmd.stop()
    atts = [bytes.fromhex(s["attachment"]) for s in seen]
    assert all(len(a) == 33 and a[16] == 0x10 for a in atts)
    seqs = [struct.unpack_from("<q", a)[0] for a in atts]
    assert seqs == list(range(seqs[0], seqs[0] + 5))
    # sequence numbers count from 1, one per message: the n-th Twist (linear 0.1·(n-1)) has n
    for s, n in zip(seen, seqs):
        linear = struct.unpack_from("<d", bytes.fromhex(s["payload"]), 4)[0]
        assert abs(linear - 0.1 * (n - 1)) < 1e-9
    stamps = [struct.unpack_from("<q", a, 8)[0] for a in atts]
    assert stamps == sorted(stamps) and stamps[0] > 1_600_000_000 * 10**9  # ns since the epoch
    assert len({a[17:] for a in atts}) == 1  # one GID for the publisher
    assert seen[0]["key"].endswith("/geometry_msgs::msg::dds_::Twist_/RIHS01_9c45bf16fe0983d8"
                                   "0e3cfe750d6835843d265a9a6c46bd2e609fcddde6fb8d2a")
    assert bytes.fromhex(seen[1]["payload"])[:4] == b"\x00\x01\x00\x00"

    graph = children.mrta("ros2", "graph", "--json", "--wait", "2", name="graph")
    assert graph.wait(30) == 0
    g = json.loads(graph.stdout[-1])
    assert {"/mrta_bridge_robot1", "/sdk_listener"} <= set(g["nodes"])
    cmd = {t["topic"]: t for t in g["topics"]}[f"/{ROBOT}/cmd_vel"]
    assert cmd["publishers"] == 1 and cmd["subscriptions"] == 1


@pytest.mark.slow
def test_the_sdk_odometry_arrives_on_our_key_and_unattached_samples_are_dropped(network, msgs):
    children, bridge = network
    echo = children.mrta("echo", f"{ROBOT}/odom", "--json", name="echo")
    odom_key = (f"0/{ROBOT}/odom/nav_msgs::msg::dds_::Odometry_/RIHS01_3cc97dc7fb7502f8714462c5"
                "26d369e35b603cfc34d946e3f2eda2766dfec6e0")
    bad = children.python("ros2_probe.py", "unattached", odom_key, "3", name="unattached")
    bad.wait_json(lambda o: o.get("sent") == 6, 30)
    driver = sdk(children, msgs, "pub-odom", f"/{ROBOT}/odom", "10")
    first = echo.wait_json(lambda o: True, 60)
    assert first["key"] == f"{ROBOT}/odom" and first["type"] == "mrta_msgs/Odometry"
    assert first["message"]["header"]["frame_id"] == f"{ROBOT}/odom"
    last = echo.wait_json(lambda o: o["message"]["pose"]["x"] == 4.5, 30)["message"]
    assert last["header"]["stamp"] == pytest.approx(109.5)
    assert last["pose"]["theta"] == pytest.approx(0.9, abs=1e-9)
    assert last["twist"] == {"linear": 0.2, "angular": 0.1}
    driver.wait_json(lambda o: o.get("published") == 10, 30)
    lines = [json.loads(x)["message"] for x in echo.stdout if x.startswith("{")]
    assert all(x["pose"]["x"] != 9.0 for x in lines)  # the unattached ones never came through
    assert [x["header"]["seq"] for x in lines] == list(range(1, len(lines) + 1))
    bridge.signal(signal.SIGTERM)
    assert bridge.wait(30) == 0
    done = next(line for line in bridge.stderr if "done:" in line)
    assert "'no_attachment': 3" in done and "'bad_attachment': 3" in done
    assert any("early-Jazzy" in line for line in bridge.stderr)


@pytest.mark.slow
def test_the_sdk_lists_our_bridge_topics_from_our_tokens(network, msgs):
    children, _ = network
    lister = sdk(children, msgs, "topic-list",
                 *(f"/{ROBOT}/{t}" for t in ("cmd_vel", "odom", "sonar")))
    assert lister.wait(60) == 0, lister.stderr[-10:]
    topics = json.loads(lister.stdout[-1])["topics"]
    assert topics[f"/{ROBOT}/cmd_vel"] == ["geometry_msgs/msg/Twist"]
    assert topics[f"/{ROBOT}/odom"] == ["nav_msgs/msg/Odometry"]
    assert topics[f"/{ROBOT}/sonar"] == ["sensor_msgs/msg/PointCloud"]


@pytest.mark.slow
def test_a_robot_whose_ros2_driver_node_disappears_is_shown_offline(network, msgs):
    """The supervisor reads the ROS 2 graph: robot1's agent is up (its token), its driver is a
    ROS 2 node in /robot1 (the SDK), and a bridge drives robot1 (its token). Kill the driver:
    robot1 goes offline with `driver_lost`, although its agent still runs — it can no longer
    move anything. (Without a bridge, a node in /robot1 is nobody's driver.)"""
    children, _ = network
    children.python("fake_robot.py", "robot1", "wander", name="agent1")
    driver = sdk(children, msgs, "driver", "/robot1")
    sup = children.mrta("supervise", "patrol", "--json", "--rate", "10", name="supervise")

    def robot1(snap):
        return {r["id"]: r for r in snap["robots"]}["robot1"]

    up = sup.wait_json(lambda s: "/robot1/sdk_driver" in s["ros2"]["nodes"]
                       and robot1(s)["state"] == "busy", 60)
    assert {t["topic"] for t in up["ros2"]["topics"]} >= {"/robot1/odom"}
    driver.signal(signal.SIGKILL)
    down = sup.wait_json(lambda s: robot1(s)["state"] == "offline", 60)
    assert "/robot1/sdk_driver" not in down["ros2"]["nodes"]
    assert {"kind": "driver_lost", "subject": "robot1"} in [
        {k: a[k] for k in ("kind", "subject")} for a in down["alarms"]]


@pytest.mark.slow
def test_a_robot_whose_bridge_dies_is_shown_offline_with_bridge_lost(network, msgs):
    """The driver lives on, the bridge is killed: the agent's commands reach nothing, so
    robot1 is offline with `bridge_lost` (not online and idle, with no alarm)."""
    children, bridge = network
    children.python("fake_robot.py", "robot1", "wander", name="agent1")
    sdk(children, msgs, "driver", "/robot1")
    sup = children.mrta("supervise", "patrol", "--json", "--rate", "10", name="supervise")

    def robot1(snap):
        return {r["id"]: r for r in snap["robots"]}["robot1"]

    sup.wait_json(lambda s: "/robot1/sdk_driver" in s["ros2"]["nodes"]
                  and robot1(s)["state"] == "busy", 60)
    bridge.signal(signal.SIGKILL)
    down = sup.wait_json(lambda s: robot1(s)["state"] == "offline", 60)
    assert "/robot1/sdk_driver" in down["ros2"]["nodes"]  # the driver still runs
    assert {"kind": "bridge_lost", "subject": "robot1"} in [
        {k: a[k] for k in ("kind", "subject")} for a in down["alarms"]]
