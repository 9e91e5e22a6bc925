"""SSI and CBBA end to end: `mrta demo --application delivery
--architecture ssi|cbba --instance FILE` in lockstep serves a 3-robot × 6-task instance — each
robot exactly the tasks of the plan the architecture converges to, in its order, computed here
from the instance (SSI restated in tests/test_ssi_auction.direct_ssi, CBBA's sequential greedy
assignment in tests/harness/cbba_reference.greedy) — and under a crash every task is still served."""

from __future__ import annotations

from pathlib import Path

import pytest

from mrta_zenoh import instances

from tests.harness.cbba_reference import greedy
from tests.test_ssi_auction import direct_ssi

pytestmark = [pytest.mark.multiprocess]

GENERATE = ["instance", "generate", "delivery", "--robots", "3", "--tasks", "6",
            "--capabilities", "", "--speeds", "0.8", "1.2", "--service", "1", "2", "--seed", "1"]


def make_instance(children, tmp_path: Path) -> Path:
    file = tmp_path / "inst.yaml"
    gen = children.mrta(*GENERATE, "-o", str(file), name="generate")
    assert gen.wait(60) == 0, gen.tail(10)
    return file


def run_demo(children, out: Path, *args: str) -> dict:
    return children.demo(out, "--application", "delivery", "--duration", "60", *args,
                         quiet=True).summary(300)


def served_orders(summary: dict) -> dict[str, list[str]]:
    out: dict[str, list[str]] = {}
    for e in sorted((e for e in summary["allocation"] if e["reason"] == "done"),
                    key=lambda e: e["done_at"]):
        out.setdefault(e["robot"], []).append(e["task"])
    return out


def converged(arch: str, file: Path) -> dict[str, list[str]]:
    p = instances.problem(file)
    routes = direct_ssi(p)[0] if arch == "ssi" else greedy(p)[0]
    return {p.robots[i].id: [p.tasks[j].id for j in r] for i, r in routes.items() if r}


@pytest.mark.slow
@pytest.mark.timeout(600)
@pytest.mark.parametrize("arch", ["ssi", "cbba"])
def test_the_executed_orders_are_the_converged_plan(children, tmp_path, arch):
    file = make_instance(children, tmp_path)
    s = run_demo(children, tmp_path / arch, "--architecture", arch, "--instance", str(file))
    assert (s["application"], s["architecture"]) == (f"delivery_{arch}", arch)
    assert s["metrics"]["completed"] == s["metrics"]["tasks"] == 6, s["metrics"]
    assert served_orders(s) == converged(arch, file)
    assert s["lockstep_exact"] is True


@pytest.mark.slow
@pytest.mark.timeout(600)
@pytest.mark.parametrize("arch", ["ssi", "cbba"])
def test_under_a_crash_every_task_is_still_served(children, tmp_path, arch):
    file = make_instance(children, tmp_path)
    plan = converged(arch, file)
    victim = next(r for r in sorted(plan) if len(plan[r]) >= 2)
    s = run_demo(children, tmp_path / arch, "--architecture", arch, "--instance", str(file),
                 "--fail", f"crash:{victim}@6")
    assert s["metrics"]["completed"] == s["metrics"]["tasks"] == 6, s["metrics"]
    done = served_orders(s)
    assert sorted(t for tasks in done.values() for t in tasks) == sorted(
        t for tasks in plan.values() for t in tasks)
    assert set(plan[victim]) - set(done.get(victim, [])), "the crash must leave it work"
