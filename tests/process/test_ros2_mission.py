"""The patrol mission with robot2 on the ROS 2 side: the simulator serves robot2 as a ROS 2
robot over rmw_zenoh (simulator/ros2.py), `mrta ros2 bridge` maps it to robot2/…, and robot2's
ALLIANCE agent drives it through the bridge like any real ROS 2 robot. Every piece is its own
process on a private loopback rendezvous."""

import json
import math
import signal

import pytest

from tests.harness.helpers import CONFIGS

pytestmark = pytest.mark.multiprocess

CONFIG = CONFIGS / "applications" / "patrol" / "config"
ROBOTS = ("robot1", "robot2", "robot3")


@pytest.mark.slow
def test_patrol_with_a_ros2_robot_allocates_every_task_and_survives_its_agent(children):
    children.mrta("sim", "--world", "patrol", *(a for r in ROBOTS for a in ("--robot", r)),
                  "--ros2", "robot2", "--speed", "2", "--wait-robots", "60", name="sim")
    bridge = children.mrta("ros2", "bridge", "--robot", "robot2", "--mirror", name="bridge")
    agents = {rid: children.mrta(
        "agent", rid, "--robot-params", str(CONFIG / f"{rid}_alliance_params.yaml"),
        "--tasks-params", str(CONFIG / "tasks_alliance_params.yaml"),
        "--layers-params", str(CONFIG / "layers_alliance_params.yaml"), "--sim-time",
        name=rid) for rid in ROBOTS}
    sup = children.mrta("supervise", "patrol", "--json", "--sim-time", "--rate", "4",
                        name="supervise")

    def tasks(snap):
        return {t["id"]: t["robots"] for t in snap["tasks"]}

    def allocated(snap):
        t = tasks(snap)
        return all(t[k] for k in ("wander", "border_protection", "report"))

    snap = sup.wait_json(allocated, 120)
    assert "/robot2/pioneer_driver" in snap["ros2"]["nodes"]
    assert "/mrta_bridge_robot2" in snap["ros2"]["nodes"]
    robot2 = {r["id"]: r for r in snap["robots"]}["robot2"]
    assert robot2["state"] == "busy", snap["robots"]
    held = robot2["task"]

    # robot2 moves: its only commands are the ROS 2 ones its driver takes from the bridge
    truth = children.mrta("echo", "robot2/ground_truth", "--json", name="truth")
    first = truth.wait_json(lambda o: True, 30)["message"]["pose"]
    truth.wait_json(lambda o: math.hypot(o["message"]["pose"]["x"] - first["x"],
                                         o["message"]["pose"]["y"] - first["y"]) > 0.5, 60)

    # ALLIANCE's own traffic is visible to ROS 2 tools (--mirror)
    graph = children.mrta("ros2", "graph", "--json", "--wait", "2", name="graph")
    assert graph.wait(30) == 0
    topics = {t["topic"]: t["types"] for t in json.loads(graph.stdout[-1])["topics"]}
    assert topics["/robot2/alliance/inter_robot_communication"] == [
        "alliance_msgs/msg/InterRobotCommunication"]
    assert topics["/robot2/cmd_vel"] == ["geometry_msgs/msg/Twist"]
    assert any(t.startswith("/robot2/alliance/motivation/") for t in topics)

    agents["robot2"].signal(signal.SIGKILL)
    after = sup.wait_json(lambda s: tasks(s)[held] and "robot2" not in tasks(s)[held], 120)
    assert {r["id"]: r["state"] for r in after["robots"]}["robot2"] == "offline"
    assert bridge.running()
