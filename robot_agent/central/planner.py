"""The dispatcher's planning: the problem left at a moment of the run, solved with the reference
solvers of `mrta_zenoh.planning`, and kept unless it improves on the current plan.

**The model's clock.** A run's objective is computed from the instance's travel-time model
along the order each robot served its tasks (planning.schedule: a robot's completions follow
from its route alone, whatever the real clock did). The dispatcher plans on that same clock:
each robot's *commitment* — what it served, then the task it set off to — is a fixed prefix
of its route; the residual problem starts each robot at its prefix's last task (or its start),
`ready` at the prefix's model completion, and holds the tasks known, not done and not
committed. So the value it minimises is the value the run will report, and by the principle of
optimality re-solving a static problem never changes an exact plan: the remainder of an
optimal plan is optimal for its residual, so the re-solve can only tie (and a tie keeps the
current plan, below). A robot's real delays do not enter; the real clock enters only through
what is known (arrivals, completions, losses).

**Kept unless better.** A new plan replaces the current one only if its value is lower by more
than rounding; otherwise the current plan, restricted to the tasks still open (and extended by
the cheapest insertion of newly arrived ones), is kept — so an exact solve never reshuffles
ties, and a best-found search (OR-Tools, which may find worse than the current plan on the same
residual) never makes the plan worse than keeping it.

**Time windows** (docs/delivery.md, "Time windows"). The residual keeps every task's window,
so a solver that plans with windows plans the residual with them; under hard windows whatever a
plan would start after its due is dropped from it (`insertion.drop_late`: left unassigned —
missed, unless a later re-plan finds it a place), the current plan is extended only at places
that keep every window (`insertion.windowed_places`), and of two plans the one that leaves
fewer tasks out wins before its value counts (a plan serving fewer tasks travels less).

**Many open tasks** (`search_limit`, 50 by default: a burst of tasks submitted at run time,
a large instance). The routing search's deterministic budget (`solutions`) grows in cost with
the tasks open — on a loaded 2-core machine ~1 CPU s at 30 tasks, 2 at 50, ~15 at 200 —, so
above `search_limit` it would run into its time cap on every re-plan (and a capped search
depends on the machine: lockstep gave a dispatcher searching 200 tasks up, and its runs could
not be replayed). Above it the plan is the current plan kept, each task it does not hold
inserted where it adds least (`keep`): deterministic, milliseconds for hundreds of tasks. It
is the SSI-like greedy (Koenig et al. 2006's insertion heuristic) rather than a search: worse
routes than the search would find, found in time. Once the open tasks fall to the limit,
re-plans search again.

**Capacities** (`max_tasks_per_robot`): a robot's residual capacity is its cap less its
commitment. Tasks no available robot may serve (capability, capacity) are left out of the
residual — unassigned until someone can take them.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from typing import Iterable, Mapping, Sequence

from mrta_zenoh.planning import Problem, Robot
from mrta_zenoh.planning.insertion import binding, drop_late, windowed_places
from mrta_zenoh.planning.schedule import Objective, evaluate, route_visits

EXACT, BEST_FOUND, KEPT = "exact", "best found", "kept"
# cheapest insertion into the current plan: more open tasks than `search_limit`, or the search
# found nothing within its time cap
INSERTION = "insertion"
TIE = 1e-9  # relative: a new plan must beat the current one by more than rounding


@dataclass(frozen=True)
class Situation:
    """What the dispatcher knows at a moment: each robot's commitment (served tasks in order,
    then the task it set off to, if any), which robots may take work, the tasks still open."""

    commitments: dict[str, tuple[str, ...]]
    available: tuple[str, ...]
    open_tasks: tuple[str, ...]


@dataclass
class Outcome:
    routes: dict[str, list[str]]       # robot → its new route after its commitment
    value: float                       # the whole plan's value (commitments included)
    method: str                        # EXACT, BEST_FOUND, KEPT
    seconds: float                     # the computation's wall time
    unassigned: list[str] = field(default_factory=list)
    # stopped by its time cap before the search found any route: the routes are cheapest
    # insertion's (INSERTION), and the decision depends on the machine
    capped: bool = False


def full_value(problem: Problem, objective: Objective, commitments: Mapping[str, Sequence[str]],
               routes: Mapping[str, Sequence[str]]) -> float:
    """The objective of every robot's commitment followed by its route (planning.schedule)."""
    full = {problem.robot_index(r): [problem.task_index(t) for t in
                                     (*commitments.get(r, ()), *routes.get(r, ()))]
            for r in {*commitments, *routes}}
    return evaluate(problem, full).value(objective)


def residual(problem: Problem, situation: Situation
             ) -> tuple[Problem, list[str], list[str], list[str]]:
    """The residual problem (module docstring), its robots' and tasks' ids in its order, and the
    open tasks it leaves out (nobody available may serve them)."""
    n = len(problem.robots)
    robots, origins = [], []
    for rid in situation.available:
        i = problem.robot_index(rid)
        base = problem.robots[i]
        prefix = [problem.task_index(t) for t in situation.commitments.get(rid, ())]
        visits = route_visits(problem, i, prefix)
        cap = None if base.capacity is None else max(0, base.capacity - len(prefix))
        robots.append(Robot(rid, base.start if not prefix else problem.tasks[prefix[-1]].position,
                            base.speed, base.capabilities,
                            visits[-1].end if visits else base.ready, cap))
        origins.append(n + prefix[-1] if prefix else i)
    room = sum(len(situation.open_tasks) if r.capacity is None else r.capacity for r in robots)
    servable = [t for t in situation.open_tasks
                if any(_can(problem, r, problem.task_index(t)) for r in robots)]
    # too few places for every task (max_tasks_per_robot): the earliest arrivals first
    order = sorted(servable, key=lambda t: (problem.tasks[problem.task_index(t)].arrival, t))
    kept = set(order[:room])
    tasks = [t for t in servable if t in kept]
    left = [t for t in situation.open_tasks if t not in kept]
    points = origins + [n + problem.task_index(t) for t in tasks]
    sub = Problem(tuple(robots), tuple(problem.tasks[problem.task_index(t)] for t in tasks),
                  tuple(tuple(problem.distance[a][b] for b in points) for a in points),
                  problem.windows)
    return sub, [r.id for r in robots], tasks, left


def _can(problem: Problem, robot: Robot, j: int) -> bool:
    need = problem.tasks[j].capability
    return (not need or need in robot.capabilities) and robot.capacity != 0


def solve(problem: Problem, situation: Situation, objective: Objective, *, exact_limit: int,
          solutions: int, time_limit: float, search_limit: int | None = None,
          current: Mapping[str, Sequence[str]] | None = None) -> Outcome:
    """The plan for `situation`: the best of a fresh solve and the current plan (kept unless
    beaten: module docstring). `search_limit` None: the search whatever the open tasks."""
    t0 = time.perf_counter()
    capped = inserted = False
    sub, robot_ids, task_ids, left = residual(problem, situation)
    if not task_ids:
        routes: dict[str, list[str]] = {r: [] for r in robot_ids}
        method = KEPT
    elif len(task_ids) <= exact_limit:
        from mrta_zenoh.planning.exact import solve_exact
        routes = _named(solve_exact(sub, objective).routes, robot_ids, task_ids)
        method = EXACT
    elif search_limit is not None and len(task_ids) > search_limit:
        # more open tasks than the routing search takes (module docstring, "Many open
        # tasks"): the current plan, each new task inserted where it adds least
        routes = keep(problem, objective, situation, current or {}, task_ids) or {
            r: [] for r in robot_ids}
        method, inserted = INSERTION, True
    else:
        from mrta_zenoh.planning.routing import SearchTimeout, solve_routing
        try:
            found = solve_routing(sub, objective, solutions=solutions, time_limit=time_limit)
            routes = _named(found.routes, robot_ids, task_ids)
            method, capped = BEST_FOUND, found.capped  # its cap: CPU s of the search
        except SearchTimeout:
            # a time cap too short for even a first solution (issue 51.2: a 1 ms time_limit
            # crashed the dispatcher): each task inserted where it adds least, reported capped
            routes = keep(problem, objective, situation, {}, task_ids) or {r: [] for r in
                                                                           robot_ids}
            method, capped = INSERTION, True
    routes = on_time(problem, situation, routes)
    value = full_value(problem, objective, situation.commitments, routes)
    if current is not None and task_ids and not inserted:
        kept = keep(problem, objective, situation, current, task_ids)
        if kept is not None:
            old = full_value(problem, objective, situation.commitments, kept)
            fresh = _planned(routes) - _planned(kept)  # > 0 under hard windows only
            if fresh < 0 or (fresh == 0 and not value < old - TIE * max(1.0, abs(old))):
                routes, value, method = kept, old, KEPT
    planned = {t for route in routes.values() for t in route}
    left += [t for t in task_ids if t not in planned]
    return Outcome(routes, value, method, time.perf_counter() - t0, left, capped)


def _planned(routes: Mapping[str, Sequence[str]]) -> int:
    return sum(len(r) for r in routes.values())


def on_time(problem: Problem, situation: Situation,
            routes: Mapping[str, Sequence[str]]) -> dict[str, list[str]]:
    """`routes` without what would start after its due, under hard windows (module
    docstring)."""
    out = {}
    for rid, route in routes.items():
        prefix = [problem.task_index(t) for t in situation.commitments.get(rid, ())]
        kept, _ = drop_late(problem, problem.robot_index(rid),
                            prefix + [problem.task_index(t) for t in route], len(prefix))
        out[rid] = [problem.tasks[j].id for j in kept[len(prefix):]]
    return out


def _named(routes: Mapping[int, Sequence[int]], robot_ids: list[str],
           task_ids: list[str]) -> dict[str, list[str]]:
    return {robot_ids[i]: [task_ids[j] for j in routes.get(i, ())]
            for i in range(len(robot_ids))}


def keep(problem: Problem, objective: Objective, situation: Situation,
         current: Mapping[str, Sequence[str]], task_ids: Sequence[str]
         ) -> dict[str, list[str]] | None:
    """The current plan on the tasks to plan: what is still open of each available robot's
    route, then each task it does not hold inserted where it adds least (None: that is not
    possible — a task nobody may take there; under hard windows such a task is left out).

    A place is valued by the whole plan's objective (`full_value`), from each robot's share
    (`Timing`) with only the trial's change computed — a burst of 200 tasks cost ~10⁶
    evaluations of the whole plan (minutes) when each trial evaluated it; equal to
    `full_value` but for rounding, which the TIE margin absorbs."""
    wanted = set(task_ids)
    routes = {r: [t for t in current.get(r, ()) if t in wanted] for r in situation.available}
    held = {t for route in routes.values() for t in route}
    index = {rid: problem.robot_index(rid) for rid in {*situation.commitments, *routes}}
    prefix = {rid: [problem.task_index(t) for t in situation.commitments.get(rid, ())]
              for rid in index}
    timing = {rid: Timing(problem, i, prefix[rid] + [problem.task_index(t)
                                                     for t in routes.get(rid, ())])
              for rid, i in index.items()}
    for task in task_ids:
        if task in held:
            continue
        best: tuple[float, str, int] | None = None
        j = problem.task_index(task)
        for rid in situation.available:
            i = index[rid]
            cap = problem.robots[i].capacity
            if not problem.capable(i, j) or (cap is not None and len(
                    prefix[rid]) + len(routes[rid]) >= cap):
                continue
            places = windowed_places(problem, i, timing[rid].stops, j)
            rest = _rest(objective, (t.share for r, t in timing.items() if r != rid))
            for place in range(len(routes[rid]) + 1):
                k = len(prefix[rid]) + place
                if places is not None and k not in places:
                    continue
                v = _with(objective, rest, timing[rid].inserted(j, k))
                if best is None or v < best[0] - TIE * max(1.0, abs(v)):
                    best = (v, rid, place)
        if best is None:
            if binding(problem):
                continue
            return None
        _, rid, place = best
        routes[rid].insert(place, task)
        stops = timing[rid].stops
        k = len(prefix[rid]) + place
        timing[rid] = Timing(problem, index[rid], stops[:k] + [j] + stops[k:])
    return routes


class Timing:
    """Robot i's stops (task indices, its commitment first), their timing as
    schedule.route_visits has it, and its share of a plan's objectives (`share`: its travel,
    the sum and the last of its completions), so that the share with one more stop is had in
    O(1) (`inserted`) — unless a later stop waits (for its arrival or window), which may absorb
    the delay: then the stops after the insertion are timed again."""

    def __init__(self, problem: Problem, i: int, stops: Sequence[int]):
        self.problem, self.i, self.stops = problem, i, list(stops)
        now, at, travel, ends = problem.robots[i].ready, None, 0.0, 0.0
        self.ends: list[float] = []      # each stop's completion
        waits: list[bool] = []           # whether the robot waits to start it
        for j in self.stops:
            task = problem.tasks[j]
            reach = now + problem.travel(i, at, j)
            waits.append(task.opens > reach)
            now = max(reach, task.opens) + task.service
            travel, ends, at = travel + problem.travel(i, at, j), ends + now, j
            self.ends.append(now)
        self.share = (travel, ends, now if self.stops else 0.0)
        # from each stop on, no stop waits (a delay there reaches every later completion)
        self.free = [True] * (len(waits) + 1)
        for k in range(len(waits) - 1, -1, -1):
            self.free[k] = self.free[k + 1] and not waits[k]

    def inserted(self, j: int, k: int) -> tuple[float, float, float]:
        """The share with task j served before stop k (k = len(stops): last)."""
        p, i, stops, ends = self.problem, self.i, self.stops, self.ends
        travel, total, last = self.share
        prev = stops[k - 1] if k else None
        task = p.tasks[j]
        leg = p.travel(i, prev, j)
        done = max((ends[k - 1] if k else p.robots[i].ready) + leg, task.opens) + task.service
        if k == len(stops):
            return travel + leg, total + done, done
        after = p.travel(i, j, stops[k])
        travel += leg + after - p.travel(i, prev, stops[k])
        nxt = p.tasks[stops[k]]
        shifted = max(done + after, nxt.opens) + nxt.service
        delay = shifted - ends[k]
        if self.free[k + 1]:  # every later completion moves by `delay`
            return travel, total + done + delay * (len(stops) - k), last + delay
        now, at, total = shifted, stops[k], total + done - sum(ends[k:]) + shifted
        for m in stops[k + 1:]:
            later = p.tasks[m]
            now = max(now + p.travel(i, at, m), later.opens) + later.service
            total, at = total + now, m
        return travel, total, now


def _rest(objective: Objective, shares: Iterable[tuple[float, float, float]]) -> float:
    """The other robots' part of a plan's objective, from their shares (`_share`)."""
    column = 0 if objective is Objective.MINSUM else 2 if objective is Objective.MAKESPAN else 1
    values = [s[column] for s in shares]
    return max(values, default=0.0) if column == 2 else sum(values)


def _with(objective: Objective, rest: float, share: tuple[float, float, float]) -> float:
    """A plan's objective (schedule.Evaluation.value): the others' `rest` and one robot's share."""
    if objective is Objective.MAKESPAN:
        return max(rest, share[2])
    return rest + (share[0] if objective is Objective.MINSUM else share[1])


def ms(seconds: float) -> float:
    """Milliseconds, to the microsecond (what a Plan message carries)."""
    return round(seconds * 1000.0, 3) if math.isfinite(seconds) else 0.0
