"""Agent hosts give the summary one process per robot gives (issue 47's identity): the same seed
run with `--agents-per-process 1` and with one host for the team (K = 5) — or 2 hosts of 3 and
2 — must agree field for field but for what measures the machine (wall time, computation
milliseconds, the output path, how far the recording reached in wall terms: the golden
summaries' comparison, supervisor/mission/compare.py). The CI tier runs
one architecture with a hosted robot's crash; the slow tier every architecture under every
fault model of the grammar."""

from __future__ import annotations

from pathlib import Path

import pytest

from mrta_supervisor.mission.compare import run_differences

pytestmark = [pytest.mark.multiprocess]

DURATION = "25"  # simulated s: the default instance's tasks are served by ≈ 23 s


def run(children, out: Path, architecture: str, fail: str, k: int) -> dict:
    return children.demo(out, "--application", "delivery", "--architecture", architecture,
                         "--fail", fail, "--duration", DURATION, "--seed", "3", "--no-plots",
                         "--agents-per-process", str(k), quiet=True,
                         name=f"demo-k{k}").summary(240)


def check_identity(children, tmp_path, architecture, fail, k=5):
    one = run(children, tmp_path / "k1", architecture, fail, 1)
    hosted = run(children, tmp_path / f"k{k}", architecture, fail, k)
    assert (tmp_path / f"k{k}" / "hosts" / "host1.yaml").exists()  # it did run in hosts
    assert hosted["run_status"] == "complete" and hosted["lockstep_exact"] is True
    # the bus's whole count within a sample per robot: each robot's last unstamped command may
    # fall either side of the recording's end, in either layout (compare.py)
    assert run_differences(one, hosted) == []
    return one, hosted


@pytest.mark.timeout(600)
def test_a_hosted_crash_gives_the_summary_of_a_process_crash(children, tmp_path):
    one, hosted = check_identity(children, tmp_path, "ssi", "robot4@10")
    # the crash struck in both (a hosted robot's crash is that robot's, not its host's)
    assert hosted["failure"]["robot"] == "robot4" and hosted["failure"]["killed_at"] == 10.0
    assert hosted["failure"]["taken_over_by"] not in (None, "robot4")


# range:R: MURDOCH, seed 3, range:4 ended task t4's allocation at 14.9 s in some runs and 15.0 s
# in others. One race was found and fixed — a range judged on receipt could meet the receiver's
# ground truths a step behind from another process, never in a host; it is judged at the tick
# now (faults.FaultInjector.cut). What is left is not the host's: on 2026-12-07 (load 20-30)
# two hosted runs agreed with each other and with one run of one process per robot, while two
# runs of one process per robot disagreed with each other (allocation[4].ended_at 14.9 / 15.0,
# t4's coverage by 0.004), with the same 264 messages dropped out of range in all four — so
# one process per robot is not yet reproducible under range:4 here, and the xfail is about
# that layout; not yet traced further (the allocation's end comes from the recorded reports)
FAULTS = ["none", "robot2@10", "stall:robot2@8", "partition:robot2@8+6", "loss:0.3",
          "latency:0.3±0.1",
          pytest.param("range:4", marks=pytest.mark.xfail(
              reason="MURDOCH under range:4: one process per robot does not yet reproduce "
                     "itself (t4's allocation ends at 14.9 or 15.0 s from run to run); the "
                     "hosted runs agreed", strict=False))]


@pytest.mark.slow
@pytest.mark.timeout(900)
@pytest.mark.parametrize("fail", FAULTS)
@pytest.mark.parametrize("architecture", ["alliance", "murdoch", "central", "ssi", "cbba"])
def test_every_architecture_and_fault_model_gives_the_same_summary_in_hosts(
        children, tmp_path, architecture, fail):
    check_identity(children, tmp_path, architecture, fail)


@pytest.mark.slow
@pytest.mark.timeout(900)
def test_two_hosts_and_the_dispatchers_crash(children, tmp_path):
    check_identity(children, tmp_path, "central", "crash:dispatcher@10", k=3)
