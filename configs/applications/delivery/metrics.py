"""What a delivery run achieved, from its recording (docs/delivery.md, "The allocation log and
the metrics").

* The allocation log: one entry per stretch a robot held a task, read through the architecture
  contract (`ground_truth.stretches_from`: ALLIANCE's motivations, MURDOCH's claims, central's
  queues — what the robots themselves said, in simulated time): when the task became the
  robot's (`assigned_at`: it entered its queue, or it took it), when the robot set off to it
  (`started_at`), reached it and began serving it (`reached_at`, its `robotN/delivery/started`),
  finished it (`done_at`, its `robotN/delivery/done`), and when and why the stretch ended
  (`ended_at`, `reason`: done, released, lost — its robot crashed or was cut off —, stalled,
  or unfinished when the run ended). A task handed over appears once per holder.
* The metrics: the time-extended objectives along the routes robots served against their
  reference values, the time-window counts and overlaps (objectives.py); makespan (the last completion), total
  distance (ground truth), mean waiting time, completed; and the instantaneous-assignment
  figures — the achieved cost (Σ cost of each task's *first* assignment, from the robot's
  start), the IA optimum (scipy's linear_sum_assignment, proven optimal) and their ratio,
  `ia_optimality` (≤ 1), with MURDOCH's greedy rule as a second reference. The achieved cost
  and the ratio exist only when the first assignments are an assignment of as many tasks as
  the optimum's: no robot in two of them (routes — central, SSI, CBBA — and a robot that took
  another task are not instantaneous assignments; their first-assignment sum fell below the
  optimum, ratios 1.05–1.17 read as better than optimal).
* The workload (issue 50, fairness): each robot's share of the work — tasks it served (each
  task's first completion, to its robot), busy time (the union of its stretches from setting off
  to the task's completion or the stretch's end) and distance driven — and the Gini coefficient
  of each over the team (`gini_served`, `gini_busy`, `gini_distance`: 0 even, (n − 1)/n one robot
  did everything; mrta_zenoh.planning.fairness).
"""

from __future__ import annotations

import bisect
import enum
import math
from dataclasses import dataclass, field
from typing import Any, Iterable

from mrta_zenoh.architectures import Architecture
from mrta_zenoh.clock import EPSILON
from mrta_zenoh.codec import DecodeError, decode, type_from_encoding
from mrta_zenoh.failure import FaultKind, Faults
from mrta_zenoh.planning import Problem
from mrta_zenoh.planning.fairness import gini
from mrta_zenoh.planning.assignment import (greedy_online, ia_costs, murdoch_utility,
                                            optimal_assignment)
from mrta_supervisor.mission.ground_truth import stretches_from

from .done_rule import DoneRule
from .instance import DeliveryParams, InstanceBody, document_data
from .keys import Event
from .messages import TaskEvent
from .objectives import (objective_metrics, objective_section, overlaps,
                         reference_window_metrics, window_metrics)
from .runtime_tasks import cancellations, changes

MATCH_SLACK = 1.0  # s: an event this long after its holder's interval still belongs to it


EVENTS = frozenset(e.value for e in Event)


class Reason(str, enum.Enum):
    """Why a stretch of the allocation log ended (module docstring; `Entry.reason`)."""

    DONE = "done"
    RELEASED = "released"
    LOST = "lost"
    STALLED = "stalled"
    UNFINISHED = "unfinished"

    def __str__(self) -> str:
        return self.value


@dataclass
class Entry:
    """One stretch: `robot` held `task` from `assigned_at` to `ended_at` (module docstring)."""

    task: str
    robot: str
    assigned_at: float
    ended_at: float
    started_at: float | None = None
    done_at: float | None = None
    reached_at: float | None = None
    reason: str = ""

    def to_json(self) -> dict[str, Any]:
        return {"task": self.task, "robot": self.robot, "assigned_at": self.assigned_at,
                "started_at": self.started_at, "reached_at": self.reached_at,
                "done_at": self.done_at, "ended_at": self.ended_at, "reason": self.reason}


@dataclass
class RunAnalysis:
    params: InstanceBody
    instance: Problem
    log: list[Entry]
    metrics: dict[str, Any] = field(default_factory=dict)
    objectives: dict[str, Any] = field(default_factory=dict)
    base: InstanceBody | None = None         # the instance before tasks at run time
    submitted: list = field(default_factory=list)  # what entered at run time (runtime_tasks)
    runtime: dict[str, Any] | None = None    # what became of it (runtime_tasks.accounting)


def events(records: Iterable) -> list[tuple[str, str, str, float]]:
    """(robot, task, event, stamp) of every well-formed delivery event on its sender's key."""
    out = []
    for key, enc, _t, payload in records:
        chunks = key.split("/")
        if len(chunks) != 3 or chunks[1] != "delivery" or chunks[2] not in EVENTS:
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


TRUTH_SLACK = 1.0  # m: beyond the layer's tolerance, how far the simulator's ground truth may
                  # put a robot from a task it says it serves (its odometry drifts)


def believed_events(records: list, params: InstanceBody, tolerance: float
                    ) -> tuple[list[tuple[str, str, str, float]], int]:
    """The delivery events a delivery is counted from, and how many others were refused: each
    as the robots' boards believe it (done_rule.py: a `done` after its sender's own `started` a
    service before, at a time it could have reached the task), and — where the recording has
    the simulator's ground truth of its sender — said where the sender really was: within
    `tolerance` + TRUTH_SLACK of the task (the latest ground truth at or before its stamp). A
    certified robot that says `started` and `done` without moving is believed by its teammates
    (docs/security.md) but its delivery is not counted here."""
    truth: dict[str, list[tuple[float, float, float]]] = {}
    for key, enc, _t, payload in records:
        robot, _, topic = key.partition("/")
        if topic != "ground_truth" or robot not in params.robots:
            continue
        try:
            msg = decode(type_from_encoding(enc), payload)
        except DecodeError:
            continue
        truth.setdefault(robot, []).append((msg.header.stamp, msg.pose.x, msg.pose.y))
    for poses in truth.values():
        poses.sort()
    rule = DoneRule(params, params.path_map())
    out, refused = [], 0
    for robot, task, event, stamp in events(records):
        if not rule.knows(robot, task):
            refused += 1
            continue
        poses = truth.get(robot) if task in params.tasks else None  # where: the instance's
        if poses:
            n = bisect.bisect_right(poses, (stamp + EPSILON, math.inf, math.inf))
            _, x, y = poses[max(n - 1, 0)]
            where = params.tasks[task].position
            if math.hypot(x - where[0], y - where[1]) > tolerance + TRUTH_SLACK:
                refused += 1
                continue
        if event == Event.STARTED:
            rule.on_started(robot, task, stamp)
        elif not rule.on_done(robot, task, stamp):
            refused += 1
            continue
        out.append((robot, task, event, stamp))
    return out, refused


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


def allocation_log(records: list, arch: Architecture, instance: Problem, end: float,
                   faults: Faults = Faults(),
                   delivery: list[tuple[str, str, str, float]] | None = None) -> list[Entry]:
    """Every stretch of an instance task, in order of assignment, with its service times and
    why it ended (module docstring). A crash ends its robot's stretches at the crash, and so
    does a stall: a stalled robot may go on saying it holds its tasks, but from then on it
    serves none (exact in lockstep). `delivery`: the events to read (believed_events; None:
    every well-formed one)."""
    tasks = {t.id for t in instance.tasks}
    robots = {r.id for r in instance.robots}
    crashes = [(f.robot, f.at) for f in faults.failures
               if f.kind in (FaultKind.CRASH, FaultKind.STALL) and f.at <= end]
    log = [Entry(s.task, s.robot, round(s.assigned_at, 3), round(s.ended_at, 3),
                 None if s.started_at is None else round(s.started_at, 3))
           for s in stretches_from(records, arch, end, arch.doing_stale_after, crashes)
           if s.robot in robots and s.task in tasks]
    for robot, task, event, stamp in events(records) if delivery is None else delivery:
        entry = next((e for e in log if e.robot == robot and e.task == task
                      and e.assigned_at - 1e-6 <= stamp <= e.ended_at + MATCH_SLACK), None)
        if entry is None:
            continue
        if event == Event.STARTED and entry.reached_at is None:
            entry.reached_at = round(stamp, 3)
        elif event == Event.DONE and entry.done_at is None:
            entry.done_at = round(stamp, 3)
    for e in log:
        e.reason = reason(e, faults, end)
    return log


def reason(e: Entry, faults: Faults, end: float) -> Reason:
    """Why a stretch ended (module docstring): from its completion, then its robot's fault."""
    if e.done_at is not None:
        return Reason.DONE
    f = faults.of(e.robot)
    if f is not None and e.ended_at >= f.at - MATCH_SLACK:
        if f.kind == FaultKind.CRASH or (f.kind == FaultKind.PARTITION
                                         and e.ended_at <= f.at + f.duration + MATCH_SLACK):
            return Reason.LOST
        if f.kind == FaultKind.STALL:
            return Reason.STALLED
    if e.ended_at >= end - EPSILON:
        return Reason.UNFINISHED
    return Reason.RELEASED


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
        if e.reached_at is not None:
            started[e.task] = min(started.get(e.task, math.inf), e.reached_at)
    first = first_assignments(log)
    best = optimal_assignment(cost)
    greedy = greedy_online(murdoch_utility(cost), [t.arrival for t in instance.tasks])
    # the IA figures compare an instantaneous assignment (each robot one task) with the IA
    # optimum: first assignments in which a robot holds two tasks (a route, a robot that took
    # another task) cost the second from the robot's start, where it never was — a sum that
    # can fall below the optimum and is no assignment's cost, so no figure at all (issue 51)
    holders = [e.robot for e in first.values()]
    achieved = float(sum(cost[rows[e.robot], cols[t]] for t, e in first.items())) \
        if len(set(holders)) == len(holders) else math.nan
    complete = len(first) == len(best.pairs) and math.isfinite(achieved)
    waits = [started[t.id] - t.arrival for t in instance.tasks if t.id in started]
    return {
        "tasks": len(instance.tasks),
        "completed": len(done),
        "assigned": len(first),
        "makespan": round(float(max(done.values())), 3) if len(done) == len(instance.tasks) else None,
        "total_distance": round(float(sum(distance.values())), 3),
        "mean_waiting_time": round(float(sum(waits)) / len(waits), 3) if waits else None,
        "achieved_cost": round(achieved, 3) if complete else None,
        "optimal_cost": round(best.cost, 3),
        "greedy_cost": round(float(sum(cost[i, j] for i, j in greedy)), 3),
        "ia_optimality": (round(best.cost / achieved, 4) if complete and achieved > 0
                          else 1.0 if complete else None),
        "online": instance.online,
        "handovers": len(log) - len(first),
        "overlaps": len(overlaps(log)),
    }


def arrivals(instance: Problem, end: float) -> dict[str, Any]:
    """How many tasks had arrived by the run's end and when the last arrives: the README's
    20-robot instance has tasks arriving up to ≈ 200 s, and a 60 s run delivered 3/20 with
    nothing saying why (issue 51, the newcomer's list)."""
    times = [t.arrival for t in instance.tasks]
    return {"arrived": sum(1 for a in times if a <= end + EPSILON),
            "last_arrival": round(max(times), 3) if times else None}


def workload(robots: list[str], log: list[Entry], distance: dict[str, float],
             end: float) -> dict[str, dict[str, float]]:
    """Each robot's share (module docstring): `served` (tasks whose first completion was its),
    `busy` (simulated s: the union of its stretches from setting off to done or the stretch's
    end, at most `end`), `idle` (the rest of `end`) and `distance` (m, ground truth)."""
    first: dict[str, Entry] = {}
    for e in sorted((e for e in log if e.done_at is not None), key=lambda e: (e.done_at, e.robot)):
        first.setdefault(e.task, e)
    spans: dict[str, list[tuple[float, float]]] = {r: [] for r in robots}
    for e in log:
        if e.started_at is not None and e.robot in spans:
            stop = min(e.done_at if e.done_at is not None else e.ended_at, end)
            if stop > e.started_at:
                spans[e.robot].append((e.started_at, stop))
    out = {}
    for r in robots:
        busy, reach = 0.0, -math.inf
        for a, b in sorted(spans[r]):  # the union: stretches of one robot may overlap
            if b > reach:
                busy += b - max(a, reach)
                reach = b
        out[r] = {"served": sum(1 for e in first.values() if e.robot == r),
                  "busy": round(busy, 3), "idle": round(max(0.0, end - busy), 3),
                  "distance": round(distance.get(r, 0.0), 3)}
    return out


def fairness(shares: dict[str, dict[str, float]]) -> dict[str, Any]:
    """The workload and its Gini coefficients over the robots (None for a team of none)."""
    def g(what: str) -> float | None:
        return round(gini(s[what] for s in shares.values()), 4) if shares else None
    return {"workload": shares, "gini_served": g("served"), "gini_busy": g("busy"),
            "gini_distance": g("distance")}


def analyse(records: list, arch: Architecture, params: InstanceBody, end: float,
            faults: Faults = Faults(), objective: str | None = None,
            tolerance: float = DeliveryParams().tolerance) -> RunAnalysis:
    """The log, the metrics and the objectives of a recorded run that ended at `end`;
    `objective`: the one its architecture optimised (default: its contract's, else MinSum);
    `tolerance`: how near a robot stops at a task (the layers file's `Delivery` section)."""
    instance = params.problem()
    delivery, refused = believed_events(records, params, tolerance)
    log = allocation_log(records, arch, instance, end, faults, delivery)
    distance = paths(records, {r.id for r in instance.robots})
    section = objective_section(instance, log, objective or arch.objective or "minsum")
    cancelled = cancellations(changes(records))
    windows = window_metrics(instance, log, end, cancelled)
    hindsight = reference_window_metrics(instance, section["reference"],
                                         windows["served_in_window"])
    if cancelled:  # the reference serves tasks the run was told to leave: no gap to it
        hindsight["served_gap"] = None
    metrics = {**measure(instance, log, distance), **arrivals(instance, end),
               "windowed": instance.windowed, **windows, **hindsight,
               **objective_metrics(section),
               **fairness(workload([r.id for r in instance.robots], log, distance, end)),
               "events_refused": refused}
    return RunAnalysis(params, instance, log, metrics, section)


def done_at(records: list, params: InstanceBody,
            tolerance: float = DeliveryParams().tolerance,
            until: float = math.inf) -> float | None:
    """When nothing of the instance was left to serve: every task completed (its first
    completion, from the robots' own `done` events as believed: believed_events) or, under hard
    windows, missed by `until` (the run's duration) — over at its due when no service of it
    was believed started, else when that service would have ended (max(due, start) +
    service) — or cancelled at run time before either (over when it was cancelled): what the
    run's task watch ends the run on (mission.DeliveryWatch). None: some task was none of
    these."""
    first: dict[str, float] = {}
    began: dict[str, float] = {}
    for _robot, task, event, stamp in believed_events(records, params, tolerance)[0]:
        if event == Event.DONE:
            first.setdefault(task, stamp)
        else:
            began[task] = min(stamp, began.get(task, stamp))
    cancelled = cancellations(changes(records))
    over = []
    for tid, t in params.tasks.items():
        if tid in first or tid in cancelled:
            over.append(min(first.get(tid, math.inf), cancelled.get(tid, math.inf)))
            continue
        if params.windows != "hard" or t.due is None:
            return None
        missed = t.due if tid not in began else max(t.due, began[tid]) + t.service
        if missed > until:
            return None
        over.append(missed)
    return max(over, default=None)


def instance_json(params: InstanceBody, instance: Problem) -> dict[str, Any]:
    """summary.json's `instance`: the instance document (fed back as `--instance`, it gives the
    same run), plus the travel-time matrix (robot × task, s; null: cannot serve) and how it was
    computed — which a document read back ignores."""
    cost = ia_costs(instance)
    body = document_data(params)
    return {"application": "delivery", **body,
            "cost": [[round(float(c), 3) if math.isfinite(c) else None for c in row]
                     for row in cost],
            "cost_model": params.travel_model()}
