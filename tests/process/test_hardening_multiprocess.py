"""Faults a tester threw at a running mission, with real processes on loopback: a stopped
observer, a forged clock, a simulator killed and restarted, a recorder killed mid-run."""

import json
import signal
import time

import msgpack
import pytest

from mrta_zenoh.recording import read_recording
from tests.harness.helpers import PATROL

pytestmark = pytest.mark.multiprocess

CONFIG = PATROL / "config"


@pytest.mark.slow
def test_a_stopped_observer_does_not_stall_the_simulator(children, tokens):
    """A Ctrl-Z'd `mrta echo '**'` must not hold `mrta sim --speed 0`: sensor data and the
    clock are lossy streams, so the simulator never waits for a stopped reader."""
    probe = children.python("clock_gaps.py", name="probe")
    tokens.wait("@mrta/test/clock_gaps", 30, probe)
    sim = children.mrta("sim", "--world", "patrol", "--robot", "robot1", "--robot", "robot2",
                        "--speed", "0", "--duration", "100000", name="sim")
    probe.wait_json(lambda o: o.get("count", 0) > 100, 60)
    echo = children.mrta("echo", "**", "--json", name="observer")
    echo.wait_line(lambda line: True, 60)  # connected and receiving
    echo.signal(signal.SIGSTOP)
    try:
        stopped = probe.wait_json(lambda o: True, 10)
        after = probe.wait_json(lambda o: o["stamp"] > stopped["stamp"], 10)
        after = probe.wait_json(lambda o: o["stamp"] > after["stamp"], 10)
        after = probe.wait_json(lambda o: o["stamp"] > after["stamp"], 10)  # 4+ s stopped
    finally:
        echo.signal(signal.SIGCONT)
    sim.stop()
    # with publishers that wait, the simulator stood still for the stopped peer's whole lease
    # (3 s) as soon as its socket buffer filled; best-effort streams never wait
    assert after["max_gap"] < 1.5, (stopped, after)


def patrol_agent(children, robot):
    return children.mrta("agent", robot, "--robot-params", CONFIG / f"{robot}_alliance_params.yaml",
                         "--tasks-params", CONFIG / "tasks_alliance_params.yaml",
                         "--layers-params", CONFIG / "layers_alliance_params.yaml", "--sim-time",
                         name="agent")


def forged_clock(children, stamp):
    payload = msgpack.packb({"stamp": stamp, "source": "forger"})
    pub = children.python("publisher.py", "clock", f"hex:rosgraph_msgs/Clock:{payload.hex()}",
                          name=f"forger {stamp}")
    pub.wait_json(lambda o: "done" in o, 30)


@pytest.mark.slow
def test_forged_clock_samples_neither_stop_nor_melt_the_fleet(children, tokens):
    sim = children.mrta("sim", "--world", "patrol", "--robot", "robot1", "--speed", "2", name="sim")
    tokens.wait("@mrta/clock_source/*", 60, sim)
    agent = patrol_agent(children, "robot1")
    agent.wait_stderr(lambda line: "activated wander" in line, 60)
    sup = children.mrta("supervise", "patrol", "--sim-time", "--json", name="supervise")
    sup.wait_json(lambda o: o["time"] > 0, 60)
    forged_clock(children, 1e9)
    forged_clock(children, float("inf"))
    before = sup.wait_json(lambda o: True, 30)
    after = sup.wait_json(lambda o: o["time"] > before["time"] + 2.0, 30)
    assert after["time"] < 1000  # never adopted the forged 1e9, nor Infinity
    robot1 = next(r for r in after["robots"] if r["id"] == "robot1")
    assert robot1["state"] == "busy" and robot1["task"] == "wander"  # the agent kept working
    motivation = children.mrta("echo", "robot1/alliance/motivation/wander", "--json", "--count",
                               "2", name="echo")
    assert motivation.wait(30) == 0
    stamps = [json.loads(x)["message"]["header"]["stamp"] for x in motivation.stdout]
    assert all(s < 1000 for s in stamps), stamps


def test_a_restarted_simulator_is_followed_and_a_dead_one_is_reported(children, tokens):
    args = ["sim", "--world", "patrol", "--robot", "robot1", "--speed", "4"]
    sim = children.mrta(*args, name="sim A")
    run_a = tokens.wait("@mrta/clock_source/*", 60, sim)
    agent = patrol_agent(children, "robot1")
    agent.wait_stderr(lambda line: "activated wander" in line, 60)
    sup = children.mrta("supervise", "patrol", "--sim-time", "--json", name="supervise")
    sup.wait_json(lambda o: o["time"] > 8.0, 60)  # the old run is well past the new run's start
    sim.signal(signal.SIGKILL)
    stopped = sup.wait_json(lambda o: any(a["kind"] == "clock_stopped" for a in o["alarms"]), 30)
    assert next(r for r in stopped["robots"] if r["id"] == "robot1")["state"] == "unknown"
    agent.wait_stderr(lambda line: "clock stopped" in line, 30)
    sim2 = children.mrta(*args, name="sim B")
    tokens.wait("@mrta/clock_source/*", 60, sim2, exclude=(run_a,))
    # the alarm cleared and time restarted with the new run (the wait fails otherwise)
    sup.wait_json(lambda o: not any(a["kind"] == "clock_stopped" for a in o["alarms"])
                  and o["time"] < stopped["time"], 60)
    agent.wait_stderr(lambda line: "new simulation run" in line, 30)
    busy = sup.wait_json(lambda o: next(r for r in o["robots"] if r["id"] == "robot1")["state"]
                         == "busy", 60)
    assert busy["time"] < stopped["time"]


@pytest.mark.slow
def test_a_killed_recorder_leaves_a_file_that_plots(children, tokens, tmp_path):
    out = tmp_path / "run.mcap"
    rec = children.mrta("record", "-o", out, name="record")
    tokens.wait("@mrta/recorder/*", 30, rec)
    robot = children.python("fake_robot.py", "robot1", "wander", name="robot1")
    tokens.wait("robot1/alliance/agent", 30, robot)
    time.sleep(3.5)  # a few seconds of the robot's traffic recorded
    rec.signal(signal.SIGKILL)
    rec.wait(10)
    records = read_recording(out)
    assert not records.complete and "recovered" in records.note
    assert any(k == "robot1/alliance/inter_robot_communication" for k, *_ in records)
    png = tmp_path / "timeline.png"
    plot = children.mrta("plot", "timeline", out, "--app", "patrol", "-o", png, name="plot")
    assert plot.wait(60) == 0, plot.stderr
    assert png.stat().st_size > 1000
    assert any("recovered" in line for line in plot.stderr)
