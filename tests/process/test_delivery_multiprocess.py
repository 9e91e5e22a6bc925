"""The delivery mission end to end under both architectures: `mrta demo --application delivery
[--architecture murdoch]` in lockstep, every task delivered, the IA optimality (`ia_optimality`:
the optimal assignment's cost over the first assignments' cost) in (0, 1] and equal to what the
recorded allocation gives, the objective's optimality (`optimality`: the reference routes'
value over the served routes') in (0, 1], and the same seed giving the same allocation."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

pytestmark = [pytest.mark.multiprocess, pytest.mark.slow]

DURATION = "40"  # simulated s: the default instance's makespan is ≈ 26 s (ALLIANCE), 23 s (MURDOCH)


def run_demo(children, out: Path, *args: str) -> dict:
    return children.demo(out, "--application", "delivery", "--duration", DURATION, *args,
                         quiet=True).summary(150)


def recorded_analysis(summary: dict, out: Path):
    """The allocation and metrics recomputed here from the recording and the package's
    instance (the hook's own functions, but from the files the run left), up to where the
    hook's analysis counts the run to: the last task's first completion once all are done,
    else the run's duration (DeliveryMission.analysis; the summary's `duration` goes on to
    the simulator's end, a second later)."""
    from mrta_agent.runtime.instance import named_instance
    from mrta_agent.runtime.params import load_layers_params
    from mrta_delivery.instance import load_document
    from mrta_delivery.metrics import analyse, done_at
    from mrta_zenoh.architectures import architecture
    from mrta_zenoh.recording import read_recording
    from mrta_zenoh.toolchain.registry import Registry
    arch = architecture(summary["architecture"])
    layers = (Registry().find(summary["application"]).path / "config"
              / f"layers_{arch.param_stem}_params.yaml")
    params = load_document(named_instance(load_layers_params(layers))).body()
    records = read_recording(out / "run.mcap")
    ended = done_at(records, params.problem())
    end = summary["duration"] if ended is None else min(ended, summary["duration"])
    return analyse(records, arch, params, end)


@pytest.mark.timeout(420)
@pytest.mark.parametrize("architecture", ["alliance", "murdoch"])
def test_every_task_is_delivered_and_optimality_comes_from_the_recorded_allocation(
        children, tmp_path, architecture):
    out = tmp_path / "a"
    s = run_demo(children, out, "--architecture", architecture)
    assert (s["mission"], s["architecture"]) == ("delivery", architecture)
    m = s["metrics"]
    print(architecture, json.dumps(m))
    assert m["completed"] == m["tasks"] == 4
    assert 0 < m["ia_optimality"] <= 1 and 0 < m["optimality"] <= 1
    again = recorded_analysis(s, out)
    first = {}
    for e in again.log:
        first.setdefault(e.task, e)
        assert e.assigned_at <= e.started_at <= e.done_at
    assert set(first) == {"t1", "t2", "t3", "t4"}
    from mrta_zenoh.planning.assignment import ia_costs
    cost = ia_costs(again.instance)
    rows = {r.id: i for i, r in enumerate(again.instance.robots)}
    cols = {t.id: j for j, t in enumerate(again.instance.tasks)}
    achieved = sum(cost[rows[e.robot], cols[t]] for t, e in first.items())
    assert m["achieved_cost"] == pytest.approx(achieved, abs=1e-3)
    assert m["ia_optimality"] == pytest.approx(m["optimal_cost"] / achieved, abs=1e-4)
    assert again.metrics == m
    # robots serve only what they can (capabilities): t1 needs lift, t3 cold
    assert first["t1"].robot in ("robot1", "robot3") and first["t3"].robot in ("robot3", "robot4")
    if "allocation" in s:  # once the runner merges the hook's sections (docs/delivery.md)
        assert s["allocation"] == [e.to_json() for e in again.log]
        assert len(s["instance"]["cost"]) == 5


@pytest.mark.timeout(420)
def test_the_same_seed_gives_the_same_allocation(children, tmp_path):
    a = run_demo(children, tmp_path / "a", "--seed", "3")
    b = run_demo(children, tmp_path / "b", "--seed", "3")
    la = recorded_analysis(a, tmp_path / "a").log
    lb = recorded_analysis(b, tmp_path / "b").log
    assert [(e.task, e.robot) for e in la] == [(e.task, e.robot) for e in lb]
    assert len(la) >= 4
    # Exactly the same times: in lockstep the simulator waits until every robot's agent is a
    # participant before step 0 (an agent that joined a step late would start its ticks at
    # t = 0.1 instead of 0, shifting its activations by a tick)
    assert la == lb
    assert a["who_did_what"] == b["who_did_what"]
    for k in ("completed", "achieved_cost", "optimal_cost", "ia_optimality", "optimality",
              "makespan"):
        assert a["metrics"][k] == b["metrics"][k]
