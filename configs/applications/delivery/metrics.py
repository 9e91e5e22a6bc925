"""What a delivery run achieved, from its recording, against the optimum (docs/delivery.md).

* The allocation log: one entry per stretch a robot held a task, read through the architecture
  contract (`ground_truth.intervals_from`: ALLIANCE's motivations, MURDOCH's claims — what the
  robots themselves decided, in simulated time), with when the robot began serving it
  (`robotN/delivery/started`) and finished it (`robotN/delivery/done`). A task handed over
  appears once per holder.
* The metrics: makespan, total distance (ground truth), mean waiting time, completed, the
  achieved cost (Σ cost of the *first* assignment of each task), the optimal cost (scipy's
  linear_sum_assignment on the instance's cost matrix: travel times along the paths robots
  drive, around the walls when there are any) and their ratio, optimality; MURDOCH's greedy
  rule on the same instance as a second reference; and the instance's reference value of each
  time-extended objective (`reference_minsum`, `reference_makespan`, `reference_flowtime`,
  `reference_proven_optimal`: docs/delivery.md, Reference values).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, Iterable

from mrta_zenoh.architectures import Architecture
from mrta_zenoh.codec import DecodeError, decode, type_from_encoding
from mrta_zenoh.planning import Problem
from mrta_zenoh.planning.assignment import (greedy_online, ia_costs, murdoch_utility,
                                            optimal_assignment)
from mrta_supervisor.ground_truth import intervals_from

from .instance import DeliveryParams, document_data
from .messages import TaskEvent

MATCH_SLACK = 1.0  # s: an event this long after its holder's interval still belongs to it


@dataclass
class Entry:
    """One assignment: `robot` held `task` from `assigned_at`."""

    task: str
    robot: str
    assigned_at: float
    released_at: float
    started_at: float | None = None
    done_at: float | None = None

    def to_json(self) -> dict[str, Any]:
        return {"task": self.task, "robot": self.robot, "assigned_at": self.assigned_at,
                "started_at": self.started_at, "done_at": self.done_at}


@dataclass
class RunAnalysis:
    params: DeliveryParams
    instance: Problem
    log: list[Entry]
    metrics: dict[str, Any] = field(default_factory=dict)


def events(records: Iterable) -> list[tuple[str, str, str, float]]:
    """(robot, task, event, stamp) of every well-formed delivery event on its sender's key."""
    out = []
    for key, enc, _t, payload in records:
        chunks = key.split("/")
        if len(chunks) != 3 or chunks[1] != "delivery" or chunks[2] not in ("started", "done"):
            continue
        try:
            msg = decode(type_from_encoding(enc), payload)
        except DecodeError:
            continue
        if not isinstance(msg, TaskEvent) or msg.event != chunks[2] \
                or msg.header.frame_id.strip("/") != chunks[0]:
            continue
        out.append((chunks[0], msg.task_id, msg.event, msg.header.stamp))
    out.sort(key=lambda e: (e[3], e[0]))
    return out


def paths(records: Iterable, robots: set[str]) -> dict[str, float]:
    """Metres each robot drove, from the simulator's ground truth."""
    last: dict[str, tuple[float, float]] = {}
    dist = {r: 0.0 for r in robots}
    for key, enc, _t, payload in records:
        robot, _, topic = key.partition("/")
        if topic != "ground_truth" or robot not in robots:
            continue
        try:
            p = decode(type_from_encoding(enc), payload).pose
        except DecodeError:
            continue
        if robot in last:
            dist[robot] += math.hypot(p.x - last[robot][0], p.y - last[robot][1])
        last[robot] = (p.x, p.y)
    return dist


def allocation_log(records: list, arch: Architecture, instance: Problem,
                   end: float) -> list[Entry]:
    """Every assignment of an instance task, in order of assignment, with its service times."""
    tasks = {t.id for t in instance.tasks}
    robots = {r.id for r in instance.robots}
    held = intervals_from(records, arch, end, arch.doing_stale_after)
    log = sorted((Entry(task, robot, round(a, 3), round(b, 3))
                  for robot, spans in held.items() if robot in robots
                  for task, a, b in spans if task in tasks),
                 key=lambda e: (e.assigned_at, e.robot))
    for robot, task, event, stamp in events(records):
        entry = next((e for e in log if e.robot == robot and e.task == task
                      and e.assigned_at - 1e-6 <= stamp <= e.released_at + MATCH_SLACK), None)
        if entry is None:
            continue
        if event == "started" and entry.started_at is None:
            entry.started_at = round(stamp, 3)
        elif event == "done" and entry.done_at is None:
            entry.done_at = round(stamp, 3)
    return log


def first_assignments(log: list[Entry]) -> dict[str, Entry]:
    """Each task's first assignment; two robots taking it on the same tick: the one that went
    on to serve it, else the lower id."""
    out: dict[str, Entry] = {}
    for e in sorted(log, key=lambda e: (e.assigned_at, e.done_at is None, e.robot)):
        out.setdefault(e.task, e)
    return out


def measure(instance: Problem, log: list[Entry], distance: dict[str, float]) -> dict[str, Any]:
    cost = ia_costs(instance)
    rows = {r.id: i for i, r in enumerate(instance.robots)}
    cols = {t.id: j for j, t in enumerate(instance.tasks)}
    done: dict[str, float] = {}
    started: dict[str, float] = {}
    for e in log:
        if e.done_at is not None:
            done[e.task] = min(done.get(e.task, math.inf), e.done_at)
        if e.started_at is not None:
            started[e.task] = min(started.get(e.task, math.inf), e.started_at)
    first = first_assignments(log)
    achieved = float(sum(cost[rows[e.robot], cols[t]] for t, e in first.items()))
    best = optimal_assignment(cost)
    greedy = greedy_online(murdoch_utility(cost), [t.arrival for t in instance.tasks])
    complete = len(first) == len(best.pairs) and math.isfinite(achieved)
    waits = [started[t.id] - t.arrival for t in instance.tasks if t.id in started]
    return {
        "tasks": len(instance.tasks),
        "completed": len(done),
        "assigned": len(first),
        "makespan": round(float(max(done.values())), 3) if len(done) == len(instance.tasks) else None,
        "total_distance": round(float(sum(distance.values())), 3),
        "mean_waiting_time": round(float(sum(waits)) / len(waits), 3) if waits else None,
        "achieved_cost": round(achieved, 3) if math.isfinite(achieved) else None,
        "optimal_cost": round(best.cost, 3),
        "greedy_cost": round(float(sum(cost[i, j] for i, j in greedy)), 3),
        "optimality": (round(best.cost / achieved, 4) if complete and achieved > 0
                       else 1.0 if complete else None),
        "online": instance.online,
        "handovers": len(log) - len(first),
    }


def analyse(records: list, arch: Architecture, params: DeliveryParams,
            end: float) -> RunAnalysis:
    instance = params.problem()
    log = allocation_log(records, arch, instance, end)
    distance = paths(records, {r.id for r in instance.robots})
    return RunAnalysis(params, instance, log,
                       {**measure(instance, log, distance), **references(instance)})


REFERENCE_SOLUTIONS = 100  # the routing search's budget past the exact limit (deterministic)


def references(instance: Problem) -> dict[str, Any]:
    """The instance's reference value for each objective (mrta_zenoh.planning.reference:
    exact — proven optimal — up to its task limit, OR-Tools' best found above), as
    `reference_<objective>`, and whether all are proven optimal. The search is bounded by a
    number of solutions, not a time (1–3 s for 10–20 tasks, ≈ 25 s for 100 robots × 100 tasks
    on a 2-core machine): the same instance gives the same values anywhere. Its time cap is
    only a safety net; a value it cut short is not reported (it would depend on the machine)."""
    from mrta_zenoh.planning.reference import reference
    out: dict[str, Any] = {}
    proven = True
    for objective in ("minsum", "makespan", "flowtime"):
        ref = reference(instance, objective, solutions=REFERENCE_SOLUTIONS, time_limit=300.0)
        out[f"reference_{objective}"] = None if ref.capped else round(ref.value, 3)
        proven = proven and ref.proven_optimal
    out["reference_proven_optimal"] = proven
    return out


def instance_json(params: DeliveryParams, instance: Problem) -> dict[str, Any]:
    """summary.json's `instance`: the instance document (fed back as `--instance`, it gives the
    same run), plus the travel-time matrix (robot × task, s; null: cannot serve) and how it was
    computed — which a document read back ignores."""
    cost = ia_costs(instance)
    body = document_data(params)
    for key in ("tolerance", "turn_rate"):
        body.pop(key, None)
    return {"application": "delivery", **body,
            "cost": [[round(float(c), 3) if math.isfinite(c) else None for c in row]
                     for row in cost],
            "cost_model": params.travel_model()}
