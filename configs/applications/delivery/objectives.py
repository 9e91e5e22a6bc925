"""What a time-extended delivery run achieved on the three objectives (docs/delivery.md,
"Objectives"), against their reference values, and whether any task was ever executed by two
robots at once — all from the allocation log, so that a summary alone gives them again.

* **Served orders.** Each robot's route as it actually ran: the tasks it completed (its own
  `done` events), in the order it completed them; a task completed twice counts once, for
  whoever completed it first.
* **Objective values** along those routes on the instance's travel-time model
  (`planning.schedule.evaluate`: MinSum = total travel, makespan = the last completion,
  flowtime = the sum of completions), beside the **reference** of each
  (`planning.reference`: exact up to `EXACT_LIMIT` tasks, proven; OR-Tools' best found above,
  never called optimal). `optimality` = reference / achieved for the objective the
  architecture optimises (its decisions' record, else its contract's `objective`, else MinSum),
  only when every task was served (a partial run's value is not comparable) and only against a
  reference proven optimal (a ratio to a best found can exceed 1: not an optimality). Each
  objective's `gap_<objective>` — achieved ÷ reference − 1, in %, lower is better — is there
  whatever the reference (benchmarks/compare_architectures.py's definition).
* **Window counts** (`window_metrics`: served in window, missed, late, lateness, early —
  `planning.schedule.window_counts`) from when each task's service actually began: the
  `reached_at` of the stretch that completed it first (its robot's `started` event), as of the
  run's end. Not along the model's timing: a robot that waited or drove slower than the model
  started where it started, and whether a window held is about that.
* **The hindsight reference's window count** (`reference_window_metrics`): how many tasks the
  reference routes serve within their windows — under hard windows the reference is
  hierarchical, most tasks in window first (planning.reference) — the best of the three
  objectives' references, so a row has its `served_gap`: that count − the run's
  `served_in_window` (tasks; lower is better). `reference_served_proven` says whether that
  count is proven the most any plan serves (an exact reference: up to EXACT_LIMIT tasks);
  above, it is the best found, a bound a run may beat (a negative gap). The reference knows
  nothing of tasks cancelled at run time, so a run with cancellations has no gap.
* **Overlaps.** A stretch is *executed* from when its robot set off to the task until it
  completed it or the task left it (`started_at` → `done_at`, else `ended_at`); two robots'
  executions of one task that overlap by more than a tick are an overlap.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Iterable, Protocol

from mrta_zenoh.errors import ConfigError
from mrta_zenoh.planning import Problem
from mrta_zenoh.planning.reference import EXACT_LIMIT, SOLUTIONS, reference
from mrta_zenoh.planning.schedule import Objective, evaluate, window_counts

TIME_LIMIT = 30.0     # its safety cap (s)
# tasks beyond which no reference is computed: a burst of 1,000 submitted tasks made the search
# spend its cap three times and then find no route, and the run ended with exit 2, no summary
REFERENCE_LIMIT = 500
OVERLAP_SLACK = 0.1   # s: a handover within one agent tick is no overlap


class Stretch(Protocol):
    task: str
    robot: str
    started_at: float | None
    done_at: float | None
    ended_at: float
    reached_at: float | None


def completing(log: Iterable[Stretch]) -> dict[str, Stretch]:
    """task → the stretch that completed it first (the earliest `done_at`)."""
    firsts: dict[str, Stretch] = {}
    for e in log:
        if e.done_at is not None and (e.task not in firsts or e.done_at < firsts[e.task].done_at):
            firsts[e.task] = e
    return firsts


def served_routes(log: Iterable[Stretch]) -> dict[str, list[str]]:
    """robot → the tasks it completed, in the order it completed them (each task once)."""
    routes: dict[str, list[tuple[float, str]]] = {}
    for task, e in completing(log).items():
        routes.setdefault(e.robot, []).append((e.done_at, task))
    return {robot: [t for _, t in sorted(done)] for robot, done in sorted(routes.items())}


def objective_values(problem: Problem, served: dict[str, list[str]]) -> dict[str, float]:
    """The three objectives along the served routes (planning.schedule.evaluate)."""
    ev = evaluate(problem, {problem.robot_index(r): [problem.task_index(t) for t in route]
                            for r, route in served.items()})
    return {o.value: ev.value(o) for o in Objective}


def service_starts(problem: Problem, log: Iterable[Stretch]) -> dict[int, float]:
    """task index → when its service began (module docstring): the completing stretch's
    `reached_at`; a completion whose `started` event the recording lacks began its service's
    length before it ended (the layer serves exactly that long)."""
    out = {}
    for task, e in completing(log).items():
        j = problem.task_index(task)
        out[j] = e.reached_at if e.reached_at is not None \
            else e.done_at - problem.tasks[j].service
    return out


def window_metrics(problem: Problem, log: Iterable[Stretch], end: float,
                   cancelled: Iterable[str] = ()) -> dict[str, Any]:
    """The run's window counts as of its end (module docstring), for `metrics`; a task
    `cancelled` at run time and not served is not missed."""
    cancelled = set(cancelled)
    withdrawn = {j for j, t in enumerate(problem.tasks) if t.id in cancelled}
    return window_counts(problem, service_starts(problem, log), end, withdrawn).to_json()


@dataclass(frozen=True)
class Overlap:
    task: str
    robots: tuple[str, str]
    start: float
    end: float

    def to_json(self) -> dict[str, Any]:
        return {"task": self.task, "robots": list(self.robots), "from": round(self.start, 3),
                "to": round(self.end, 3)}


def overlaps(log: Iterable[Stretch]) -> list[Overlap]:
    """Every pair of robots' executions of one task that overlap (module docstring)."""
    spans: dict[str, list[tuple[float, float, str]]] = {}
    for e in log:
        if e.started_at is None:
            continue
        finish = e.done_at if e.done_at is not None else e.ended_at
        spans.setdefault(e.task, []).append((e.started_at, max(finish, e.started_at), e.robot))
    out = []
    for task, runs in sorted(spans.items()):
        runs.sort()
        for k, (a0, a1, ra) in enumerate(runs):
            for b0, b1, rb in runs[k + 1:]:
                lo, hi = max(a0, b0), min(a1, b1)
                if ra != rb and hi - lo > OVERLAP_SLACK:
                    out.append(Overlap(task, (ra, rb), lo, hi))
    return out


def references(problem: Problem) -> dict[str, dict[str, Any]]:
    """Each objective's reference value on the whole instance (module docstring), with the
    routes that give it."""
    out = {}
    for objective in Objective:
        try:
            if len(problem.tasks) > REFERENCE_LIMIT:
                raise ConfigError(f"{len(problem.tasks)} tasks, more than {REFERENCE_LIMIT}")
            ref = reference(problem, objective, exact_limit=EXACT_LIMIT, time_limit=TIME_LIMIT,
                            solutions=SOLUTIONS)
        except ConfigError as exc:  # none found (or not looked for): the run is still summed up
            out[objective.value] = {"value": None, "method": "none", "proven_optimal": False,
                                    "stopped_by_time_limit": True, "routes": {},
                                    "why": str(exc)}
            continue
        out[objective.value] = {"value": round(ref.value, 6), "method": ref.method,
                                "proven_optimal": ref.proven_optimal,
                                "stopped_by_time_limit": ref.capped,
                                "routes": ref.routes_by_id(problem)}
    return out


def reference_window_metrics(problem: Problem, refs: dict[str, dict[str, Any]],
                             served_in_window: int) -> dict[str, Any]:
    """The hindsight reference's served-in-window count, whether it is proven, and the run's
    gap to it (module docstring); None for an instance without windows, or when every
    reference's search was cut by its time cap (its count would depend on the machine)."""
    counts = []
    for ref in refs.values():
        if ref["stopped_by_time_limit"]:
            continue
        routes = {problem.robot_index(r): [problem.task_index(t) for t in route]
                  for r, route in ref["routes"].items()}
        counts.append((evaluate(problem, routes).windows.served_in_window,
                       ref["proven_optimal"]))
    if not problem.windowed or not counts:
        return {"reference_served_in_window": None, "reference_served_proven": None,
                "served_gap": None}
    best, proven = max(counts)  # a proven count is the most any plan serves: ties prefer it
    return {"reference_served_in_window": best, "reference_served_proven": proven,
            "served_gap": best - served_in_window}


def objective_section(problem: Problem, log: list[Stretch], objective: str,
                      refs: dict[str, dict[str, Any]] | None = None) -> dict[str, Any]:
    """summary.json's `objectives`: the objective optimised, the served routes, their values,
    the references, optimality."""
    served = served_routes(log)
    values = objective_values(problem, served)
    refs = references(problem) if refs is None else refs
    complete = sum(len(r) for r in served.values()) == len(problem.tasks)
    achieved, best = values[objective], refs[objective]["value"]
    # a ratio to a best found is no optimality: a run may beat it (above 1) — its gap says it
    ratio = (best / achieved if achieved > 0 else 1.0) \
        if complete and refs[objective]["proven_optimal"] else None
    return {"objective": objective, "served": served,
            "values": {k: round(v, 6) for k, v in values.items()},
            "complete": complete, "reference": refs,
            "optimality": None if ratio is None or not math.isfinite(ratio)
            else round(ratio, 6)}


def gap(achieved: float | None, reference: float | None) -> float | None:
    """achieved ÷ reference − 1, in % (lower is better; below 0 the run beat a best found);
    None without both, or against a reference of 0."""
    if achieved is None or not reference:
        return None
    return round((achieved / reference - 1.0) * 100.0, 3)


def objective_metrics(section: dict[str, Any]) -> dict[str, Any]:
    """The section's scalars, for `metrics` (results.csv's columns)."""
    refs, values = section["reference"], section["values"]
    out: dict[str, Any] = {"objective": section["objective"]}
    for name in (o.value for o in Objective):
        out[f"objective_{name}"] = round(values[name], 3) if section["complete"] else None
        # a search its time cap cut short gave a value that depends on the machine: not a column
        out[f"reference_{name}"] = None if refs[name]["stopped_by_time_limit"] \
            else round(refs[name]["value"], 3)
        out[f"gap_{name}"] = gap(out[f"objective_{name}"], out[f"reference_{name}"])
    out["reference_method"] = refs[section["objective"]]["method"]
    out["reference_proven_optimal"] = all(r["proven_optimal"] for r in refs.values())
    out["optimality"] = None if section["optimality"] is None \
        else round(section["optimality"], 4)
    return out
