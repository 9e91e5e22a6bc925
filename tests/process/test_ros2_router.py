"""Through a robot's rmw_zenohd, with the bridge's default options.

A robot runs rmw_zenohd — a router that does not broker between peers — and its nodes listen on
the robot's localhost only, so from another host nobody reaches them directly. Here: a router
with rmw_zenohd's settings on a free loopback port (tests/procs/ros2_rmw_router.py), the robot's
driver as a peer that listens nowhere (tests/procs/ros2_robot_node.py), and `mrta ros2 bridge
--connect` to the router with no --mode: the bridge must default to client mode, or it hears
nothing (a peer gets 0 samples and 0 tokens through such a router, measured)."""

import pytest

from tests.harness.helpers import free_port

pytestmark = pytest.mark.multiprocess

ROBOT = "robot1"


@pytest.mark.slow
def test_cmd_vel_odom_and_sonar_flow_through_a_router_that_does_not_broker(children, tmp_path):
    port = free_port()
    robot_router = f"tcp/127.0.0.1:{port}"
    router = children.python("ros2_rmw_router.py", str(port), name="rmw_zenohd")
    router.wait_json(lambda o: o.get("ready"), 30)
    robot = children.python("ros2_robot_node.py", str(port), ROBOT, str(tmp_path), name="robot")
    robot.wait_json(lambda o: o.get("ready"), 30)
    children.mrta("ros2", "bridge", "--robot", ROBOT, "--connect", robot_router, name="bridge")
    echo = children.mrta("echo", f"{ROBOT}/**", "--json", "--connect", robot_router,
                         "--mode", "client", name="echo")
    odom = echo.wait_json(lambda o: o.get("key") == f"{ROBOT}/odom", 60)
    assert odom["message"]["pose"]["y"] == pytest.approx(2.0)
    sonar = echo.wait_json(lambda o: o.get("key") == f"{ROBOT}/sonar", 60)
    assert sonar["message"]["points"][0]["x"] == pytest.approx(1.0, abs=1e-6)
    children.env["PROBE_CONNECT"] = robot_router
    children.python("ros2_probe.py", "cmd", ROBOT, "600", name="cmd")
    got = robot.wait_json(lambda o: "cmd" in o and o["cmd"][0] > 0, 60)
    assert got["cmd"][1] == pytest.approx(-0.2)
