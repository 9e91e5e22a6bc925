"""Observers under attack, against real processes: a `mrta supervise` subprocess, `--once`,
`mrta view` and `mrta ros2 graph` while a forger session (the test's own, on the children's
free loopback port) declares invalid ROS 2 tokens, a fake driver node, a robot outside the
application, a type name and a participant name holding terminal escapes; and an agent with
`--team` beside robots outside it that claim every task. The pure state is tested in
tests/test_observers_hostile.py."""

import json
import signal
import threading
import time

import pytest

from mrta_agent.alliance.messages import InterRobotCommunication
from mrta_zenoh.lockstep.protocol import STATUS, LockstepStatus
from mrta_zenoh.messages import Header
from mrta_zenoh.ros2 import names
from mrta_zenoh.untrusted import visible
from tests.harness.alliance_fixtures import robot_yaml, tasks_yaml, write

pytestmark = pytest.mark.multiprocess

BAD_TOKEN = "@ros2_lv/0/abcd/2/2/NN/%/%a-b/node"
ESC = "\x1b]0;pwned\x07\x1b[2J"


def alarms(snap):
    return {(a["kind"], a["subject"]) for a in snap["alarms"]}


def robot(snap, rid):
    return {r["id"]: r for r in snap["robots"]}[rid]


def raw_controls(lines):
    return [line for line in lines if "\x1b" in line or "\x07" in line]


@pytest.mark.slow
def test_forged_tokens_keys_and_names_neither_stop_nor_blind_the_observers(children, tokens,
                                                                           tmp_path):
    sup = children.mrta("supervise", "patrol", "--json", "--rate", "10", name="supervise")
    r1 = children.python("fake_robot.py", "robot1", "wander", name="robot1")
    tokens.wait("robot1/alliance/agent", 30, r1)
    sup.wait_json(lambda s: robot(s, "robot1")["state"] == "busy", 30)

    forger = tokens.bus  # its own Zenoh session on the children's loopback port
    held = [forger.declare_absolute_token(BAD_TOKEN),
            forger.declare_token("robot9/alliance/agent")]
    fake = forger.declare_absolute_token(names.node_token(0, "f0", 1, "/robot1", "fake_driver"))
    stop = threading.Event()

    def keep_forging():  # repeated, so that observers started later hear it too
        while not stop.is_set():
            forger.publish("robot9/alliance/inter_robot_communication",
                           InterRobotCommunication(Header("robot9", time.time(), 1),
                                                   "not a task id!", 1.0))
            forger.publish_raw("robot1/alliance/inter_robot_communication",
                               "application/msgpack;" + ESC, b"\x80")
            forger.publish(STATUS, LockstepStatus(time.time(), (ESC,)))
            stop.wait(0.2)

    thread = threading.Thread(target=keep_forging, daemon=True)
    thread.start()
    try:
        expected = {("ros2_invalid_token", "@ros2_lv/0/**"), ("unknown_robot", "robot9"),
                    ("participant_unresponsive", visible(ESC))}
        snap = sup.wait_json(lambda s: expected <= alarms(s)
                             and "/robot1/fake_driver" in s["ros2"]["nodes"], 30)
        assert snap["ros2"]["invalid_tokens"] >= 1 and snap["counts"]["wrong_type"] >= 1
        # the one-shot observers run while the invalid token lives (each exited 2 before)
        once = children.mrta("supervise", "patrol", "--once", name="once")
        graph = children.mrta("ros2", "graph", "--json", "--wait", "2", name="graph")
        view = children.mrta("view", "patrol", "--no-server", "-o", tmp_path / "v.mcap",
                             "--duration", "3", name="view")
        for c in (once, graph, view):
            assert c.wait(90) == 0, (c.name, c.stderr[-10:])
        listed = json.loads(graph.stdout[-1])
        assert listed["invalid_tokens"] >= 1 and "/robot1/fake_driver" in listed["nodes"]
        assert any("robot1" in line for line in once.stdout)
        assert not raw_controls(once.stdout + once.stderr + view.stderr)
        # the fake driver vanishes: it takes nothing with it (robot1 has no bridge)
        fake.close()
        gone = sup.wait_json(lambda s: "/robot1/fake_driver" not in s["ros2"]["nodes"], 30)
        later = sup.wait_json(lambda s: s["time"] >= gone["time"] + 1.0, 30)
        assert robot(later, "robot1")["state"] == "busy"
        assert not any(kind == "driver_lost" for kind, _ in alarms(later))
        held[0].close()
        sup.wait_json(lambda s: ("ros2_invalid_token", "@ros2_lv/0/**") not in alarms(s), 30)
    finally:
        stop.set()
        thread.join(5)
    assert sup.running()
    sup.signal(signal.SIGTERM)
    assert sup.wait(10) == 0
    assert not raw_controls(sup.stdout + sup.stderr)
    assert any("\\x1b]0;pwned" in line for line in sup.stderr)  # logged, escaped


@pytest.mark.slow
def test_robots_outside_the_team_cannot_hold_it_back(children, tokens, tmp_path):
    """robot7–9 hold agent tokens and claim the task (expected 1000 s): an agent that believed
    them would wait ~1000 s at the slow rate. With `--team` it ignores them and takes the task
    at the fast rate (θ 100 / 10 per tick at 10 Hz: about 1 s)."""
    tf = write(tmp_path / "tasks.yaml", tasks_yaml(["A"]))
    rf = write(tmp_path / "robot1.yaml", robot_yaml([{"task": "A", "fast": 10.0, "theta": 100.0}],
                                                    spin=10.0, broadcast=5.0, tau=1.0))
    strangers = children.python("stranger_robots.py", "A", "robot7", "robot8", "robot9",
                                name="strangers")
    tokens.wait_all([f"robot{i}/alliance/agent" for i in (7, 8, 9)], 30, strangers)
    echo = children.mrta("echo", "robot1/alliance/inter_robot_communication", "--json", name="echo")
    tokens.subscribed("robot1/alliance/inter_robot_communication", 30, echo)
    feeder = children.python("sensor_feeder.py", "robot1", name="feeder")
    tokens.wait("@mrta/test/feeder", 30, feeder)
    agent = children.mrta("agent", "robot1", "--robot-params", rf, "--tasks-params", tf,
                          "--team", "robot1,robot2,robot3", name="robot1")
    tokens.wait("robot1/alliance/agent", 30, agent)
    t_up = time.time()
    took = echo.wait_json(lambda o: "message" in o, 30)
    assert took["message"]["task_id"] == "A"
    print(f"robot1 took A {took['message']['header']['stamp'] - t_up:.2f} s after its token, "
          "beside robot7-9 claiming it")
    agent.wait_stderr(lambda line: "is not on the team" in line, 30)
    agent.signal(signal.SIGTERM)
    assert agent.wait(10) == 0
