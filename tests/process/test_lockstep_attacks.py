"""Lockstep and the clock under attack and faults, with real processes on one loopback
rendezvous: a forged step, a ghost StepDone, clock creep, a simulator
restarted under lockstep, a stopped agent, and lockstep with no participant. The pure logic is
unit-tested in tests/test_lockstep_trust.py."""

import json
import signal
import sys
import time

import pytest

from tests.harness.helpers import PATROL, PROCS, Child

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


@pytest.mark.slow
def test_one_forged_step_moves_no_agent(children, tokens):
    s, agents, sup, run = lockstep_fleet(children, tokens)
    forge(children, "step", run)                  # stamp 1e9, the real run id
    agents["robot1"].wait_stderr(lambda line: "rejected" in line, 30)
    before = sup.wait_json(lambda o: True, 30)
    sup.wait_json(lambda o: o["time"] > before["time"] + 3.0, 60)  # the world goes on
    assert agent_time(children, "robot1") < before["time"] + 60


@pytest.mark.slow
def test_a_ghost_stepdone_freezes_nobody(children, tokens):
    s, agents, sup, run = lockstep_fleet(children, tokens)
    forge(children, "ghost", run)                 # 10⁹ samples claimed, by no participant
    s.wait_stderr(lambda line: "ghost" in line and "no participant token" in line, 30)
    before = sup.wait_json(lambda o: True, 30)
    after = sup.wait_json(lambda o: o["time"] > before["time"] + 5.0, 60)
    assert agent_time(children, "robot1") > before["time"]
    assert not any("did not finish" in line for line in s.stderr), s.tail()
    assert after


@pytest.mark.slow
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


@pytest.mark.slow
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
    # timeout they would take minutes
    sup.wait_json(lambda o: restarted["time"] + 8.0 < o["time"] < 20.0, 30)
    assert time.monotonic() - t0 < 25
    assert not any("did not finish" in line for line in s2.stderr), s2.tail()
    busy = sup.wait_json(lambda o: next(r for r in o["robots"] if r["id"] == "robot1")["state"]
                         == "busy", 30)
    assert busy["time"] < 20.0


@pytest.mark.slow
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


@pytest.mark.slow
def test_lockstep_with_robots_expected_and_no_participant_is_an_error(children):
    s = sim(children, ["robot1"], "--lockstep", "--wait-robots", "1")
    assert s.wait(60) == 1
    assert any("no participant" in line and "participant/" in line for line in s.stderr), \
        s.tail()


# ------------------------------------------------ one forged sample, one claimant

def forger(children, *args):
    """A forger started, and ready (its first line printed)."""
    f = children.python("lockstep_forger.py", *args, name=f"forger {args[0]}")
    f.wait_json(lambda o: o.get("ready"), 60)
    return f


def goes_on(s, sup, robot="robot1", children=None, seconds=5.0):
    """The fleet goes on, in step: the world and the agent's own time move `seconds` further,
    and nobody was given up (the simulator running on alone would move the world only)."""
    before = sup.wait_json(lambda o: True, 30)
    sup.wait_json(lambda o: o["time"] > before["time"] + seconds, 60)
    assert agent_time(children, robot) > before["time"] + seconds / 2
    assert not any("no longer waited for" in line for line in s.stderr), s.tail()


@pytest.mark.slow
def test_a_copied_step_numbered_a_billion_stops_nobody(children, tokens):
    """Before: every agent refused every real step afterwards ("step 63 after step
    1000000000"), and the simulator gave them up after 30 s and ran on alone."""
    s, agents, sup, run = lockstep_fleet(children, tokens)
    copied = forger(children, "copy", run).wait_json(lambda o: "copied" in o, 60)
    assert copied["copied"] > 0
    agents["robot1"].wait_stderr(lambda line: "skips ahead" in line, 30)
    goes_on(s, sup, children=children)


@pytest.mark.slow
def test_an_old_whole_step_replayed_as_the_next_one_heals(children, tokens):
    """The danger: all agents stuck — the forged number shadowing the real next step, and
    the replayed table making every later step unreadable."""
    s, agents, sup, run = lockstep_fleet(children, tokens)
    replayed = forger(children, "replay", run, "3").wait_json(lambda o: "replayed" in o, 60)
    assert replayed["as_step"] > replayed["replayed"] and replayed["keys"] > 0
    goes_on(s, sup, children=children)
    assert not any("did not finish" in line for line in s.stderr), s.tail()


@pytest.mark.slow
@pytest.mark.parametrize("keys, chars", [(4096, 0), (4000, 1024)])
def test_a_participant_claiming_thousands_of_keys_freezes_nobody(children, tokens, keys, chars):
    """Before: every Step counted the claimant's keys (4,096 of them, or 4,000 of 1 KB: a Step
    past 4 MiB) and every participant refused it while the claimant held its token."""
    s, agents, sup, run = lockstep_fleet(children, tokens)
    f = forger(children, "claims", run, str(keys), str(chars))
    f.wait_json(lambda o: "claiming" in o, 60)
    s.wait_stderr(lambda line: "'ghost''s claims dropped" in line, 30)
    goes_on(s, sup, children=children)
    assert f.wait_json(lambda o: "done" in o, 60)
    assert not any("rejected" in line for line in agents["robot1"].stderr), \
        agents["robot1"].tail()


@pytest.mark.slow
def test_a_claim_that_keeps_descending_pauses_the_run_once(children, tokens):
    """A claim lowered by 1 every 5.2 s withdraws each forgiveness; were the fleet paused
    again each time it would run at 6 % of its speed (8 pauses in 45 s). One pause per
    claimant per FORGIVE_WINDOW: the run's status counts one forgiveness."""
    s, agents, sup, run = lockstep_fleet(children, tokens)
    status = children.mrta("echo", "lockstep/status", "--json", name="status")
    f = forger(children, "descend", run, "22")
    assert f.wait_json(lambda o: "done" in o, 90)
    goes_on(s, sup, children=children)
    forgiven = [json.loads(line)["message"]["forgiven"] for line in status.stdout
                if line.startswith("{")]
    assert forgiven and max(forgiven) == 1, (forgiven, s.tail())


@pytest.mark.slow
@pytest.mark.timeout(420)
def test_a_certified_robot_claiming_thousands_of_keys_cannot_freeze_a_secured_fleet(
        children, tmp_path):
    """Before: robot1's own certificate was enough — it claimed 4,096 keys of its own and
    robot2 stayed at t = 5.2 for the 45 s watched."""
    from click.testing import CliRunner

    from mrta_zenoh.cli.main import cli
    from tests.harness.helpers import free_port
    from tests.test_secure import wait_accepting

    folder, endpoint = tmp_path / "fleet", f"tls/127.0.0.1:{free_port()}"
    result = CliRunner().invoke(cli, ["secure", "init", str(folder), "--robot", "robot1",
                                      "--robot", "robot2", "--observer", "supervisor",
                                      "--endpoint", endpoint])
    assert result.exit_code == 0, result.output
    router = children.mrta("router", "--zenoh-config", folder / "router.json5", name="router")
    router.wait_stderr(lambda line: "router listening on tls/" in line, 30)
    wait_accepting(endpoint)
    s = children.mrta("sim", "--world", "patrol", "--robot", "robot1", "--robot", "robot2",
                      "--speed", "4", "--lockstep", "--wait-robots", "60", "--zenoh-config",
                      folder / "simulator.json5", name="sim")
    agents = {r: children.mrta("agent", r, "--robot-params", CONFIG / f"{r}_alliance_params.yaml",
                               "--tasks-params", CONFIG / "tasks_alliance_params.yaml",
                               "--layers-params", CONFIG / "layers_alliance_params.yaml",
                               "--sim-time", "--zenoh-config", folder / f"{r}.json5", name=r)
              for r in ("robot1", "robot2")}
    s.wait_stderr(lambda line: "lockstep with 2 participants" in line, 90)
    sup = children.mrta("supervise", "patrol", "--sim-time", "--json", "--zenoh-config",
                        folder / "supervisor.json5", name="supervise")
    sup.wait_json(lambda o: o["time"] > 2.0, 60)
    # robot1's own certificate: it may answer as robot1, claiming keys of its own
    env = dict(children.env, MRTA_FORGER_CONFIG=str(folder / "robot1.json5"))
    f = Child([sys.executable, str(PROCS / "lockstep_forger.py"), "claims", "any", "4096", "0"],
              env, "forger robot1")
    children.all.append(f)
    f.wait_json(lambda o: "claiming" in o and o["name"] == "robot1", 60)
    s.wait_stderr(lambda line: "'robot1''s claims dropped" in line, 30)
    before = sup.wait_json(lambda o: True, 30)
    sup.wait_json(lambda o: o["time"] > before["time"] + 5.0, 60)
    assert agent_time_secured(children, folder, "robot2") > before["time"] + 2.5
    assert not any("no longer waited for" in line for line in s.stderr), s.tail()
    assert agents["robot2"].running()


def agent_time_secured(children, folder, robot, task="wander"):
    echo = children.mrta("echo", f"{robot}/alliance/motivation/*", "--json", "--count", "1",
                         "--zenoh-config", folder / "supervisor.json5", name="echo")
    assert echo.wait(60) == 0, echo.tail()
    return json.loads(echo.stdout[-1])["message"]["header"]["stamp"]
