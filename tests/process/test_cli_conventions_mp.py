"""The command line's conventions checked on real processes: Ctrl-C exits 130 (the
agent, the demo), `mrta supervise` into a pipe writes as it goes, with times from its start
and JSON that names its clocks."""

from __future__ import annotations

import json
import os
import signal
import time

import pytest

from tests.harness.helpers import PATROL
from tests.test_mission_hygiene import children_of

pytestmark = pytest.mark.multiprocess

CONFIG = PATROL / "config"


def agent_args(robot: str = "robot1") -> list:
    return ["agent", robot, "--robot-params", CONFIG / f"{robot}_alliance_params.yaml",
            "--tasks-params", CONFIG / "tasks_alliance_params.yaml",
            "--layers-params", CONFIG / "layers_alliance_params.yaml"]


@pytest.mark.slow
@pytest.mark.parametrize("sig,code", [(signal.SIGINT, 130), (signal.SIGTERM, 0)],
                         ids=["ctrl-c-exits-130", "sigterm-is-a-clean-stop"])
def test_an_agent_stopped_by_a_signal_exits_as_a_script_expects(children, tokens, sig, code):
    """Ctrl-C is 130, not 0: a script must tell an interrupted agent from one that ended;
    SIGTERM is a clean stop (0)."""
    agent = children.mrta(*agent_args(), name="agent")
    tokens.wait("robot1/alliance/agent", 60, agent)
    agent.signal(sig)
    assert agent.wait(20) == code, agent.tail(10)


@pytest.mark.slow
@pytest.mark.timeout(150)
def test_ctrl_c_of_the_demo_exits_130_whatever_its_children_did(children, tmp_path):
    """A terminal's Ctrl-C reaches the demo's children too, and the simulator may end by it
    before the demo handles its own SIGINT: that is neither "the simulator failed" (exit 1)
    nor a finished run (exit 0), but the mission's interruption: 130."""
    demo = children.demo(tmp_path / "out", "--duration", "600", "--speed", "1")
    demo.wait_line(lambda line: line.startswith("t="), 90)  # the mission runs
    kids = children_of(demo.proc.pid)
    assert len(kids) >= 5, kids  # recorder, simulator, three agents
    for pid in kids:
        os.kill(pid, signal.SIGINT)
    # the summary of the run so far, saying it was interrupted (issue 51, the newcomer's list)
    s = demo.summary(60, code=130)
    assert s["interrupted"] == "Ctrl-C" and s["run_status"] == "incomplete"
    assert 0 < s["recorded_until"] < 600
    assert any("INTERRUPTED: the run was interrupted (Ctrl-C)" in line for line in demo.stdout)
    assert demo.stderr[-1].startswith("Aborted! the run so far is in"), demo.stderr


@pytest.mark.slow
@pytest.mark.timeout(150)
def test_sigterm_of_the_demo_is_a_clean_stop_with_a_summary(children, tmp_path):
    """SIGTERM — a service manager's "please stop" — exits 0 as every other command does
    (it exited 130 as if Ctrl-C), after the summary of the run so far (issue 51)."""
    demo = children.demo(tmp_path / "out", "--duration", "600", "--speed", "1")
    demo.wait_line(lambda line: line.startswith("t=") and float(line[2:].split("s")[0]) >= 10,
                   120)  # 10 s of the mission ran
    demo.signal(signal.SIGTERM)
    s = demo.summary(60)
    assert s["interrupted"] == "SIGTERM" and 10 <= s["recorded_until"] < 600
    assert s["who_did_what"]["robot1"], s["who_did_what"]  # what ran is there


@pytest.mark.slow
def test_supervise_into_a_pipe_writes_each_change_at_once_with_times_from_its_start(children):
    """Into a pipe rich's live table wrote nothing until the end; times were epoch seconds."""
    sup = children.mrta("supervise", "patrol", name="supervise")
    line = sup.wait_line(lambda x: x.startswith("t="), 30)
    t = float(line.split("s", 1)[0][2:])
    assert 0 <= t < 60, line  # seconds since it started, not 1795480671.6
    assert "robot1:" in line and "robot3:" in line
    assert sup.running()
    sup.signal(signal.SIGTERM)
    assert sup.wait(15) == 0


@pytest.mark.slow
def test_supervise_json_names_its_clocks(children):
    sup = children.mrta("supervise", "patrol", "--json", name="supervise")
    snap = sup.wait_json(lambda s: "robots" in s, 30)
    assert snap["sim_time"] is None and abs(snap["wall_time"] - time.time()) < 30
    assert snap["time"] == pytest.approx(snap["wall_time"], abs=5)  # wall clock: the same
    sup.signal(signal.SIGTERM)
    assert sup.wait(15) == 0
    for line in sup.stdout:
        json.loads(line)
