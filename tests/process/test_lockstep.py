"""Lockstep simulation time with real processes: the same seed gives the same run whatever the
machine's load; a dead participant is no longer waited for; a hung one is reported and, after
the limit, no longer waited for; one still computing past the limit is waited for."""

import signal
import subprocess
import sys

import pytest

from mrta_zenoh import codec
from mrta_zenoh.recording import read_recording
from tests.harness.helpers import PATROL

pytestmark = pytest.mark.multiprocess

CONFIG = PATROL / "config"


def trace(out):
    """Activation times from the agents' own stamps, and ground-truth poses at every 2 s."""
    activations, poses = {}, {}
    for key, enc, _, payload in read_recording(out / "run.mcap"):
        if "/alliance/motivation/" in key:
            m = codec.decode(codec.type_from_encoding(enc), payload)
            was = activations.setdefault((key.split("/")[0], m.task_id), [])
            if m.active and (not was or was[-1][1] is None):
                was.append((m.header.stamp, None))
            elif not m.active and was and was[-1][1] is None:
                was[-1] = (was[-1][0], m.header.stamp)
        elif key.endswith("/ground_truth"):
            m = codec.decode(codec.type_from_encoding(enc), payload)
            if abs(m.header.stamp / 2 - round(m.header.stamp / 2)) < 1e-6:
                poses[(key.split("/")[0], round(m.header.stamp, 2))] = (m.pose.x, m.pose.y,
                                                                       m.pose.theta)
    return activations, poses


@pytest.mark.slow
@pytest.mark.timeout(300)
def test_the_same_seed_gives_the_same_run_under_load(children, tmp_path):
    args = ("--duration", "30", "--fail", "robot2@18", "--seed", "7")
    # each ≈ 5 s on an idle machine; three in one test stay within its 300 s
    children.demo(tmp_path / "quiet", *args).summary(90)
    burners = [subprocess.Popen([sys.executable, "-c", "while True: pass"]) for _ in range(2)]
    try:
        children.demo(tmp_path / "loaded", *args).summary(90)
    finally:
        for b in burners:
            b.kill()
            b.wait()
    children.demo(tmp_path / "other", "--duration", "30", "--fail", "robot2@18", "--seed",
                  "8").summary(90)
    quiet, loaded, other = (trace(tmp_path / d) for d in ("quiet", "loaded", "other"))
    assert quiet[0] == loaded[0]              # the same activations at the same times, exactly
    assert quiet[1] == loaded[1] and len(quiet[1]) >= 3 * 15   # the same poses, bit for bit
    assert ("robot2", "border_protection") in quiet[0]
    assert quiet[1] != other[1]               # another seed: another run


def start(children, *robots, timeout="5"):
    sim = children.mrta("sim", "--world", "patrol", *sum((["--robot", r] for r in robots), []),
                        "--speed", "4", "--lockstep", "--lockstep-timeout", timeout,
                        "--wait-robots", "60", name="sim")
    agents = {r: children.mrta("agent", r, "--robot-params", CONFIG / f"{r}_alliance_params.yaml",
                               "--tasks-params", CONFIG / "tasks_alliance_params.yaml",
                               "--layers-params", CONFIG / "layers_alliance_params.yaml",
                               "--sim-time", name=r) for r in robots}
    sim.wait_stderr(lambda line: f"lockstep with {len(robots)} participants" in line, 90)
    return sim, agents


def test_a_killed_participant_is_no_longer_waited_for_and_its_task_is_taken_over(children):
    sim, agents = start(children, "robot1", "robot2", "robot3")
    agents["robot2"].wait_stderr(lambda line: "activated border_protection" in line, 60)
    sup = children.mrta("supervise", "patrol", "--sim-time", "--json", name="supervise")
    sup.wait_json(lambda o: o["time"] > 3.0, 60)
    agents["robot2"].signal(signal.SIGKILL)
    taken = sup.wait_json(lambda o: next(t for t in o["tasks"] if t["id"] == "border_protection")
                          ["robots"] in (["robot1"], ["robot3"]), 60)
    sup.wait_json(lambda o: o["time"] > taken["time"] + 5.0, 60)  # the world goes on
    assert not any("no longer waited for" in line for line in sim.stderr)  # death ≠ hang


@pytest.mark.slow
def test_a_hung_participant_is_reported_and_after_the_limit_no_longer_waited_for(children):
    sim, agents = start(children, "robot1", "robot2", timeout="2")
    agents["robot1"].wait_stderr(lambda line: "activated" in line, 60)
    sup = children.mrta("supervise", "patrol", "--sim-time", "--json", name="supervise")
    sup.wait_json(lambda o: o["time"] > 2.0, 60)
    agents["robot2"].signal(signal.SIGSTOP)
    try:
        alarm = sup.wait_json(lambda o: any(a["kind"] == "participant_unresponsive" and
                                            a["subject"] == "robot2" for a in o["alarms"]), 60)
        sim.wait_stderr(lambda line: "robot2 did not finish" in line, 10)
        sup.wait_json(lambda o: o["time"] > alarm["time"] + 3.0, 60)  # it goes on without robot2
    finally:
        agents["robot2"].signal(signal.SIGCONT)


@pytest.mark.slow
def test_a_participant_computing_past_the_limit_is_waited_for_and_the_run_stays_exact(children):
    """A participant whose loop computes for 6 s of wall at t=1 s, under a 2 s limit: it says
    it is working (its loop thread uses CPU time), the simulator waits for it instead of giving
    it up, and it goes on in step — where a SIGSTOP'd one (above) says nothing and is given up."""
    sim = children.mrta("sim", "--world", "patrol", "--robot", "robot1", "--speed", "4",
                        "--lockstep", "--lockstep-timeout", "2", "--wait-robots", "60",
                        name="sim")
    busy = children.python("busy_participant.py", "robot1", "1.0", "6.0", "4.0", name="robot1")
    busy.wait_json(lambda o: o.get("computed") == 6.0, 120)
    busy.wait_json(lambda o: o.get("time", 0) >= 3.0, 120)  # in step again, after it
    assert any("robot1 still computing t=1.00" in line for line in sim.stderr), sim.stderr[-5:]
    assert not any("no longer waited for" in line for line in sim.stderr), sim.stderr[-5:]


PROBE = """
import sys
import {modules}
from mrta_zenoh.bus import BusOptions
from mrta_zenoh.bus.inproc import InProcBus
from mrta_zenoh.node import Node, NodeTime
# the node each process starts (an agent's in lockstep, an observer's on simulated time)
Node(BusOptions(), "{role}", name="robot1", time=NodeTime.{time}, bus=InProcBus())
print(",".join(sorted(m for m in sys.modules if m.startswith("mrta_zenoh.lockstep."))))
"""


@pytest.mark.parametrize("modules, role, time, loaded", [
    # an agent: its clock and books, never the simulator's barrier
    ("mrta_agent.runtime.host, mrta_agent.alliance.cli", "robot", "LOCKSTEP",
     "mrta_zenoh.lockstep.books,mrta_zenoh.lockstep.participant,mrta_zenoh.lockstep.protocol,"
     "mrta_zenoh.lockstep.sequence,mrta_zenoh.lockstep.table"),
    # observers and the access-control generator: the protocol only; and the runner the file
    # through which it tells the barrier which of its processes ended (lockstep/ended.py)
    ("mrta_supervisor.live.api, mrta_supervisor.mission.runner, mrta_zenoh.secure", "observer", "SIM",
     "mrta_zenoh.lockstep.ended,mrta_zenoh.lockstep.protocol"),
])
def test_each_process_loads_only_the_lockstep_it_needs(modules, role, time, loaded):
    out = subprocess.run([sys.executable, "-c", PROBE.format(modules=modules, role=role,
                                                               time=time)],
                         capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == loaded
