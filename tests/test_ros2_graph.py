"""The ROS 2 graph from liveliness tokens, and what the supervisor makes of it: nodes and topics
as `ros2 node list` / `ros2 topic list -v` show them, and a robot whose driver node is gone shown
offline (in-process, driven token by token)."""

from mrta_zenoh.ros2 import names
from mrta_zenoh.ros2.graph import Ros2Graph
from mrta_zenoh.ros2.names import COMMANDS, SENSOR_DATA
from mrta_supervisor.live.api import resolve_application
from mrta_supervisor.live.state import Supervisor

HASH = "RIHS01_" + "0" * 64
DRIVER = names.node_token(0, "z1", 1, "/robot2", "pioneer_driver")
ODOM = names.endpoint_token(0, "z1", 1, 2, "MP", "/robot2", "pioneer_driver", "/robot2/odom",
                            "nav_msgs/msg/Odometry", HASH, SENSOR_DATA)
BRIDGE = names.node_token(0, "z2", 1, "/", "mrta_bridge_robot2")
BRIDGE_ODOM = names.endpoint_token(0, "z2", 1, 3, "MS", "/", "mrta_bridge_robot2", "/robot2/odom",
                                   "nav_msgs/msg/Odometry", HASH, SENSOR_DATA)
BRIDGE_CMD = names.endpoint_token(0, "z2", 1, 4, "MP", "/", "mrta_bridge_robot2",
                                  "/robot2/cmd_vel", "geometry_msgs/msg/Twist", HASH, COMMANDS)


def test_nodes_topics_and_who_drives_whom():
    g = Ros2Graph(0)
    for key in (DRIVER, ODOM, BRIDGE, BRIDGE_ODOM, BRIDGE_CMD):
        g.on_token(key, True)
    g.on_token(names.node_token(5, "z3", 1, "/robot9", "other_domain"), True)
    g.on_token("@ros2_lv/0/broken", True)
    assert g.nodes() == ["/mrta_bridge_robot2", "/robot2/pioneer_driver"]
    assert g.robot_nodes() == {"robot2": ["/robot2/pioneer_driver"]}
    assert g.topics() == [
        {"topic": "/robot2/cmd_vel", "types": ["geometry_msgs/msg/Twist"], "publishers": 1,
         "subscriptions": 0},
        {"topic": "/robot2/odom", "types": ["nav_msgs/msg/Odometry"], "publishers": 1,
         "subscriptions": 1}]
    assert g.invalid == 1
    g.on_token(ODOM, False)
    assert g.topics()[1]["publishers"] == 0


def test_a_robot_is_offline_once_its_ros2_driver_node_is_gone():
    app, arch = resolve_application("patrol")
    sup = Supervisor(arch, app, 0.0)
    sup.on_liveliness("robot2/alliance/agent", True, 1.0)
    sup.on_liveliness("robot1/alliance/agent", True, 1.0)
    assert {r["id"]: r["state"] for r in sup.snapshot(1.0)["robots"]}["robot2"] == "idle"
    sup.on_bridge_token("@mrta/ros2_bridge/robot2", True, 1.5)  # robot2 is driven via ROS 2
    sup.on_ros2_token(DRIVER, True, 2.0)
    sup.on_ros2_token(BRIDGE, True, 2.0)  # our bridge is not robot2's driver
    snap = sup.snapshot(2.0)
    assert snap["ros2"]["nodes"] == ["/mrta_bridge_robot2", "/robot2/pioneer_driver"]
    assert {r["id"]: r["state"] for r in snap["robots"]}["robot2"] == "idle"
    sup.on_ros2_token(DRIVER, False, 3.0)
    snap = sup.snapshot(3.0)
    states = {r["id"]: r["state"] for r in snap["robots"]}
    assert states["robot2"] == "offline" and states["robot1"] == "idle"  # agent alive, no driver
    assert [(a["kind"], a["subject"]) for a in snap["alarms"]] == [("driver_lost", "robot2")]
    sup.on_ros2_token(DRIVER, True, 4.0)
    snap = sup.snapshot(4.0)
    assert {r["id"]: r["state"] for r in snap["robots"]}["robot2"] == "idle"
    assert not snap["alarms"]


def test_the_live_view_has_a_ros2_line_once_there_are_nodes():
    import io

    from rich.console import Console

    from mrta_supervisor.live.view import render

    app, arch = resolve_application("patrol")
    sup = Supervisor(arch, app, 0.0)

    def shown() -> str:
        buf = io.StringIO()
        Console(file=buf, width=120, color_system=None).print(render(sup.snapshot(1.0), 120))
        return buf.getvalue()

    assert "ROS 2" not in shown()
    for key in (DRIVER, ODOM, BRIDGE):
        sup.on_ros2_token(key, True, 1.0)
    assert "ROS 2 (domain 0): /mrta_bridge_robot2, /robot2/pioneer_driver · 1 topic" in shown()
