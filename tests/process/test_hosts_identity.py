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
    # both exact first: a baseline disturbed by a starved machine is named as such, not
    # reported as a difference the hosts made
    for name, summary in (("one process per robot", one), (f"{k} robots a host", hosted)):
        assert (summary["run_status"], summary["lockstep_exact"]) == ("complete", True), name
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
# in others. Two races, both fixed: a range judged on receipt could meet the receiver's ground
# truths a step behind (judged at the tick now: faults.FaultInjector.cut); and robot2's `done` of
# t4 stamped 11.9 reached robot5 — holding t4 too — before its tick at 11.9 in a host (robot2
# ticks first, and its own samples are handed over at once) but only sometimes from another
# process, so robot5's stall of t4 began at 11.9 or 12.0 and its release came 3 s later. A
# teammate's `done` now counts from the tick after its instant (delivery's board.Board.is_done),
# as a cancellation does: t4 ends at 15.0 s in both layouts (one pair, 2026-12-08)
FAULTS = ["none", "robot2@10", "stall:robot2@8", "partition:robot2@8+6", "loss:0.3",
          "latency:0.3±0.1", "range:4"]


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
