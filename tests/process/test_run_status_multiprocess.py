"""An honest run status, with real processes: `mrta demo` in lockstep while one of its processes
is stopped (SIGSTOP) longer than its Zenoh lease, then resumed — a lease of 3 s given the run
($MRTA_LEASE), as every run had before a lockstep run's processes got lockstep's 30 s:

* the recorder: what was published while its session was down never reaches the file — the
  summary says `incomplete`, names the recorder, and `mrta demo` exits 1;
* robot1's agent: its participant token goes, so the simulator runs on without it — the summary
  is complete but `disturbed`, names robot1 with when it went and came back, and the run is
  not called exact (an experiment runs it again).

And with the lease a lockstep run gives its processes (supervisor/mission/runner.py,
run_lease): the recorder stopped as long — a machine so busy it got no CPU — holds the run back
and misses nothing: the summary is complete and exact, and the demo exits 0 (issue 51: the
README's 20-robot walkthrough exited 1 at load 25 for that)."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import time
from pathlib import Path

import pytest

from mrta_zenoh.bus.options import LEASE_ENV
from tests.harness.helpers import descendants

pytestmark = [pytest.mark.multiprocess, pytest.mark.slow]

STOP_FOR = 6.0  # wall s: twice the 3 s lease, so its token surely goes (nothing is timed by it)
SHORT_LEASE = "3"  # s, the runs that must see a token go: the default outside lockstep


def find(pid: int, *needles: str) -> int:
    """The process below `pid` whose command line holds every one of `needles`."""
    deadline = time.monotonic() + 60
    while time.monotonic() < deadline:
        for d in descendants(pid):
            try:
                argv = Path(f"/proc/{d}/cmdline").read_bytes().decode(errors="replace").split("\0")
            except OSError:
                continue
            if all(n in argv for n in needles):
                return d
        time.sleep(0.2)
    raise AssertionError(f"no process {needles} below {pid}")


def stop_for_a_while(demo, victim: int) -> None:
    """Once the mission's simulated time passed 10 s (its progress lines), SIGSTOP `victim`
    for STOP_FOR wall seconds, then SIGCONT it (always: nothing is left stopped)."""
    demo.wait_line(lambda line: line.startswith("t=") and float(line[2:].split("s")[0]) >= 10,
                   120)
    os.kill(victim, signal.SIGSTOP)
    try:
        time.sleep(STOP_FOR)  # the fault itself: a stop longer than the lease
    finally:
        os.kill(victim, signal.SIGCONT)


def run_demo(children, out: Path, stopping: tuple[str, ...], lease: str | None = SHORT_LEASE):
    if lease is not None:
        children.env[LEASE_ENV] = lease
    demo = children.demo(out, "--duration", "40", "--speed", "1", "--fail", "none",
                         "--no-plots")
    stop_for_a_while(demo, find(demo.proc.pid, *stopping))
    return demo


@pytest.mark.timeout(300)
def test_a_recorder_stopped_past_its_lease_makes_the_summary_incomplete_and_the_demo_fail(
        children, tmp_path):
    demo = run_demo(children, tmp_path / "out", ("view", "--output"))
    s = demo.summary(240, code=1)  # written all the same
    print(json.dumps({k: s[k] for k in ("run_status", "disturbances", "recorded_until")}))
    assert s["run_status"] == "incomplete" and s["lockstep_exact"] is False
    (lost,) = [d for d in s["disturbances"] if d["process"] == "recorder"]
    assert 10.0 <= lost["lost_at"] <= 40.0
    assert not [d for d in s["disturbances"] if d["process"] != "recorder"]  # the rest ran on
    assert any(line.startswith("  NOT EXACT: the recording does not cover the whole mission")
               for line in demo.stdout), demo.stdout
    assert any("Error: the recording does not cover the whole mission" in line
               for line in demo.stderr), demo.stderr


@pytest.mark.timeout(300)
def test_an_agent_stopped_past_its_lease_makes_the_run_disturbed_not_exact(children, tmp_path):
    demo = run_demo(children, tmp_path / "out", ("robot_agent/agent", "robot1"))
    s = demo.summary(240)  # the summary covers the whole mission
    print(json.dumps({k: s[k] for k in ("run_status", "disturbances", "recorded_until")}))
    assert s["run_status"] == "disturbed" and s["lockstep_exact"] is False
    assert s["recorded_until"] == pytest.approx(40.0, abs=1.0)
    (lost,) = s["disturbances"]
    assert lost["process"] == "robot1" and 10.0 <= lost["lost_at"] < lost["back_at"] <= 40.0
    assert any(line.startswith("  NOT EXACT: a process of the run was stopped or cut off "
                               "(robot1 lost its token at") for line in demo.stdout), demo.stdout


@pytest.mark.timeout(600)
def test_a_recorder_starved_within_the_runs_lease_holds_the_run_back_and_misses_nothing(
        children, tmp_path):
    children.env.pop(LEASE_ENV, None)
    demo = run_demo(children, tmp_path / "out", ("view", "--output"), lease=None)
    try:
        s = demo.summary(270)
    except subprocess.TimeoutExpired:
        pytest.fail("the demo did not end:\n" + demo.tail(40))
    print(json.dumps({k: s[k] for k in ("run_status", "disturbances", "recorded_until")}))
    assert s["run_status"] == "complete" and s["lockstep_exact"] is True
    assert s["disturbances"] == [] and s["recorded_until"] == pytest.approx(40.0, abs=1.0)
    assert not any("NOT EXACT" in line for line in demo.stdout), demo.stdout
    # what nobody stopped gives: the same seed at full speed, the same robots' reports
    again = children.demo(tmp_path / "again", "--duration", "40", "--fail", "none",
                          "--no-plots").summary(270)
    assert s["who_did_what"] == again["who_did_what"] and s["coverage"] == again["coverage"]
