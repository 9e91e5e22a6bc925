"""Lockstep and the clock under attack and faults, with real processes on one loopback
rendezvous (issue 23, item 1): a forged step, a ghost StepDone, clock creep, a simulator
restarted under lockstep, a stopped agent, and lockstep with no participant. The pure logic is
unit-tested in tests/test_lockstep_trust.py."""

import json
import signal
import time

import pytest

from tests.helpers import PATROL

pytestmark = pytest.mark.multiprocess

CONFIG = PATROL / "config"


def agent(children, robot):
    return children.mrta("agent", robot, "--robot-params", CONFIG / f"{robot}_alliance_params.yaml",
                         "--tasks-params", CONFIG / "tasks_alliance_params.yaml",
                         "--layers-params", CONFIG / "layers_alliance_params.yaml", "--sim-time",
                         name=robot)


def sim(children, robots, *extra, name="sim"):
    return children.mrta("sim", "--world", "patrol", *sum((["--robot", r] for r in robots), []),
                         *extra, name=name)


def lockstep_fleet(children, tokens, robots=("robot1",), speed="4"):
    s = sim(children, robots, "--speed", speed, "--lockstep", "--wait-robots", "60")
    agents = {r: agent(children, r) for r in robots}
    s.wait_stderr(lambda line: f"lockstep with {len(robots)} participant" in line, 90)
    run = tokens.wait("@mrta/lockstep/barrier/*", 30, s).rsplit("/", 1)[-1]
    sup = children.mrta("supervise", "patrol", "--sim-time", "--json", name="supervise")
    sup.wait_json(lambda o: o["time"] > 2.0, 60)
    return s, agents, sup, run


def forge(children, *args):
    f = children.python("lockstep_forger.py", *args, name=f"forger {args[0]}")
    return f.wait_json(lambda o: "done" in o, 60)


def agent_time(children, robot, task="wander"):
    """The agent's own simulated time: the stamp of its next motivation sample."""
    echo = children.mrta("echo", f"{robot}/alliance/motivation/{task}", "--json", "--count", "1",
                         name="echo")
    assert echo.wait(60) == 0, echo.tail()
    return json.loads(echo.stdout[-1])["message"]["header"]["stamp"]


def test_one_forged_step_moves_no_agent(children, tokens):
    s, agents, sup, run = lockstep_fleet(children, tokens)
    forge(children, "step", run)                  # stamp 1e9, the real run id
    agents["robot1"].wait_stderr(lambda line: "rejected" in line, 30)
    before = sup.wait_json(lambda o: True, 30)
    sup.wait_json(lambda o: o["time"] > before["time"] + 3.0, 60)  # the world goes on
    assert agent_time(children, "robot1") < before["time"] + 60


def test_a_ghost_stepdone_freezes_nobody(children, tokens):
    s, agents, sup, run = lockstep_fleet(children, tokens)
    forge(children, "ghost", run)                 # 10⁹ samples claimed, by no participant
    s.wait_stderr(lambda line: "ghost" in line and "no participant token" in line, 30)
    before = sup.wait_json(lambda o: True, 30)
    after = sup.wait_json(lambda o: o["time"] > before["time"] + 5.0, 60)
    assert agent_time(children, "robot1") > before["time"]
    assert not any("did not finish" in line for line in s.stderr), s.tail()
    assert after


def test_clock_creep_is_bounded_by_the_runs_speed(children, tokens):
    s = sim(children, ["robot1"], "--speed", "2")
    run = tokens.wait("@mrta/clock_source/*", 60, s).rsplit("/", 1)[-1]
    a = agent(children, "robot1")
    a.wait_stderr(lambda line: "activated wander" in line, 60)
    sup = children.mrta("supervise", "patrol", "--sim-time", "--json", name="supervise")
    sup.wait_json(lambda o: o["time"] > 1.0, 60)
    f = children.python("lockstep_forger.py", "creep", run, "300", name="forger creep")
    forged = f.wait_json(lambda o: "forged_to" in o, 60)
    assert forged["forged_to"] > forged["from"] + 2900  # what the probe sent: ≈ 2,970 s ahead
    f.wait_json(lambda o: "done" in o, 30)
    snap = sup.wait_json(lambda o: True, 30)
    # 1.5 s of forging at speed 2: at most 10 s of burst + 3 s/s ahead of the real clock
    assert snap["time"] < forged["from"] + 40, (snap["time"], forged)
    assert agent_time(children, "robot1") < forged["from"] + 40
    later = sup.wait_json(lambda o: o["time"] > snap["time"] + 2.0, 60)  # and time goes on
    assert later


def test_lockstep_after_a_simulator_restart_runs_at_full_speed(children, tokens):
    s, agents, sup, run = lockstep_fleet(children, tokens)
    sup.wait_json(lambda o: o["time"] > 20.0, 60)  # well past where the new run starts
    s.signal(signal.SIGKILL)
    s.wait(10)
    tokens.wait_gone(f"@mrta/lockstep/barrier/{run}", 30)
    s2 = sim(children, ["robot1"], "--speed", "4", "--lockstep", "--wait-robots", "60",
             name="sim B")
    t0 = time.monotonic()
    agents["robot1"].wait_stderr(lambda line: "new simulation run" in line, 60)
    restarted = sup.wait_json(lambda o: o["time"] < 10.0, 60)
    # at speed 4, 8 simulated seconds take 2 s of wall time; with every step waiting a
    # timeout (the old defect) they took minutes
    sup.wait_json(lambda o: restarted["time"] + 8.0 < o["time"] < 20.0, 30)
    assert time.monotonic() - t0 < 25
    assert not any("did not finish" in line for line in s2.stderr), s2.tail()
    busy = sup.wait_json(lambda o: next(r for r in o["robots"] if r["id"] == "robot1")["state"]
                         == "busy", 30)
    assert busy["time"] < 20.0


def test_a_stopped_agent_rejoins_the_current_step(children, tokens):
    s, agents, sup, run = lockstep_fleet(children, tokens, ("robot1", "robot2"))
    agents["robot2"].wait_stderr(lambda line: "activated" in line, 60)
    agents["robot2"].signal(signal.SIGSTOP)
    try:
        stopped = sup.wait_json(lambda o: True, 30)
        # beyond the 3 s Zenoh lease: reported at 2.5 s ("did not finish"), then no longer a
        # participant once its token goes with its session — not given up (30 s)
        sup.wait_json(lambda o: o["time"] > stopped["time"] + 12.0, 60)
    finally:
        agents["robot2"].signal(signal.SIGCONT)
    resumed = sup.wait_json(lambda o: True, 30)
    # robot2 rejoins the current step: its own time catches up with the world's
    deadline = time.monotonic() + 60
    while True:
        now = sup.wait_json(lambda o: True, 30)["time"]
        mine = agent_time(children, "robot2")
        if mine > resumed["time"]:
            break
        assert time.monotonic() < deadline, (mine, resumed["time"], now)
    assert s.wait_stderr(lambda line: "robot2 did not finish" in line, 5)
    later = sup.wait_json(lambda o: o["time"] > resumed["time"] + 8.0, 60)
    assert later


def test_lockstep_with_robots_expected_and_no_participant_is_an_error(children):
    s = sim(children, ["robot1"], "--lockstep", "--wait-robots", "1")
    assert s.wait(60) == 1
    assert any("no participant" in line and "participant/" in line for line in s.stderr), \
        s.tail()
