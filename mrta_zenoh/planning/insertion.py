"""Inserting a task into a robot's route without re-ordering the rest: what sequential
single-item auctions (SSI) and the Consensus-Based Bundle Algorithm (CBBA) bid, and the
sequential greedy algorithm (SGA) that CBBA provably reproduces.

A route is served in order from an *origin*: the robot's start at time 0 before it has served
anything, later the last task it served and when it finished it (`Origin`). The timing along a
route is `schedule.py`'s (reach, then start = max(reach, arrival, earliest), then end = start +
service), from the origin instead of from the start at 0.

* **MinSum insertion** (SSI's bid, Lagoudakis et al. 2005): the increase in the route's travel
  time when task j goes between two consecutive stops, at the cheapest place.
* **Discounted insertion** (CBBA's marginal score, Choi, Brunet & How 2009, §IV-A): the route's
  score is Σ λ^start · reward over its tasks; a task's marginal score is the largest increase of
  that score over every place it can go. That score does not always diminish as the route
  grows (a task added on the way to another makes the other cheaper to reach), which the
  paper's guarantees assume; `prefix_scores` gives the least of a task's marginal scores over
  the route's earlier stages, which does (docs/cbba.md, "Diminishing marginal gain").

**Time windows** (docs/delivery.md, "Time windows"). Timing waits for a task's `earliest`
(`Task.opens`). Under hard windows a task goes only where it starts by its due and makes no
task of the route late that was not (`late`); with no such place, MinSum insertion costs ∞ and
the discounted score is 0 — CBBA's rule for an infeasible task in Choi et al.'s scoring
extended to time windows (Ponda et al., "Decentralized planning for complex missions with
dynamic communication constraints", ACC 2010: a task is inserted only where its window and those
of the path's later tasks still hold, its score otherwise 0). Soft windows change no place:
lateness is counted, not forbidden.

Ties between places go to the earliest one: the rule both algorithms state, so two
implementations of the same instance agree whatever their rounding.

Pure Python (agents import it while they bid; no numpy).
"""

from __future__ import annotations

import math
from typing import NamedTuple, Sequence

from .problem import Problem, Windows
from .schedule import WINDOW_TOLERANCE


class Origin(NamedTuple):
    """Where and when a robot's remaining route begins: after serving task `task` (None: from
    its start), free from time `time`."""

    task: int | None = None
    time: float = 0.0


def ranks(ids: Sequence[str]) -> list[int]:
    """Each id's place in id order: "lower id" in every tie rule of SSI and CBBA, as MURDOCH
    ranks robots (plain string order: robot10 comes before robot2)."""
    order = sorted(range(len(ids)), key=lambda k: ids[k])
    out = [0] * len(ids)
    for place, k in enumerate(order):
        out[k] = place
    return out


def minsum_insertion(problem: Problem, i: int, route: Sequence[int], j: int,
                     origin: int | None = None, at: float = 0.0,
                     places: range | None = None) -> tuple[float, int]:
    """(added travel time, place) of the cheapest place for task j in robot i's `route` leaving
    from task `origin` (None: its start) at time `at`; place n means before route[n]
    (len(route): at the end). Under hard windows only places that keep them (module docstring),
    and only `places` when given (SSI's priority band): (∞, len(route)) when there is none."""
    allowed = windowed_places(problem, i, route, j, Origin(origin, at))
    if places is not None:
        allowed = places if allowed is None else allowed & set(places)
    best, where = math.inf, len(route) if allowed is not None else 0
    prev = origin
    for n in range(len(route) + 1):
        to_j = problem.travel(i, prev, j)
        if n < len(route):
            nxt = route[n]
            added = to_j + problem.travel(i, j, nxt) - problem.travel(i, prev, nxt)
            prev = nxt
        else:
            added = to_j
        if added < best and (allowed is None or n in allowed):
            best, where = added, n
    return best, where


def binding(problem: Problem) -> bool:
    """Whether windows restrict where a task may go: hard windows on some task."""
    return problem.windows is Windows.HARD and problem.windowed


def late(problem: Problem, i: int, route: Sequence[int], origin: Origin = Origin()) -> set[int]:
    """The tasks of `route` whose service would start after their due."""
    return {j for j, t in zip(route, starts(problem, i, route, origin))
            if t > problem.tasks[j].due + WINDOW_TOLERANCE}


def drop_late(problem: Problem, i: int, route: Sequence[int], fixed: int = 0,
              origin: Origin = Origin()) -> tuple[list[int], list[int]]:
    """(kept, dropped): `route` without the tasks that would start after their due, walked in
    order (dropping one lets the rest start sooner); its first `fixed` tasks are kept whatever
    (a robot's commitment). Nothing is dropped where windows do not bind."""
    if not binding(problem):
        return list(route), []
    kept, dropped = list(route[:fixed]), []
    for j in route[fixed:]:
        if starts(problem, i, [*kept, j], origin)[-1] > problem.tasks[j].due + WINDOW_TOLERANCE:
            dropped.append(j)
        else:
            kept.append(j)
    return kept, dropped


def windowed_places(problem: Problem, i: int, route: Sequence[int], j: int,
                    origin: Origin = Origin()) -> set[int] | None:
    """The places of task j in `route` that keep the windows (module docstring); None: windows
    bind nowhere here, every place will do."""
    if not binding(problem):
        return None
    before = late(problem, i, route, origin)
    return {n for n in range(len(route) + 1)
            if late(problem, i, [*route[:n], j, *route[n:]], origin) <= before}


def starts(problem: Problem, i: int, route: Sequence[int],
           origin: Origin = Origin()) -> list[float]:
    """When robot i starts serving each task of `route` (schedule.route_visits' `start`, from
    `origin`)."""
    out = []
    now, at = origin.time, origin.task
    for j in route:
        task = problem.tasks[j]
        start = max(now + problem.travel(i, at, j), task.opens)
        out.append(start)
        now, at = start + task.service, j
    return out


def discounted_value(problem: Problem, i: int, route: Sequence[int], discount: float,
                     origin: Origin = Origin()) -> float:
    """Σ discount^start · reward over `route`: CBBA's time-discounted reward (Choi et al. 2009,
    eq. 12) with the start of service as the arrival time at a task."""
    return sum(discount ** t * problem.tasks[j].reward
               for j, t in zip(route, starts(problem, i, route, origin)))


def travel_times(problem: Problem, i: int) -> list[list[float]]:
    """Robot i's travel time between every two points (robots' starts, then tasks): what its
    bids read thousands of times, divided once."""
    speed = problem.robots[i].speed
    return [[d / speed for d in row] for row in problem.distance]


class DiscountedRoute:
    """Robot i's route with its timing computed once, so that the best place of each candidate
    task costs one pass over the places. A delay inserted at a place passes unchanged through
    the tasks that do not wait for their arrival — their part of the score is summed once
    (`_weight`) — and shrinks at each task that waits, where it is followed exactly (a wait
    that absorbs it ends the pass, leaving the score untouched)."""

    def __init__(self, problem: Problem, i: int, route: Sequence[int], discount: float,
                 origin: Origin = Origin(), times: list[list[float]] | None = None):
        self.problem, self.i, self.route = problem, i, list(route)
        self.discount, self.origin = discount, origin
        self.times = times if times is not None else travel_times(problem, i)
        n = len(problem.robots)
        self.point = [n + j for j in self.route]  # rows of `times`
        self.home = i if origin.task is None else n + origin.task
        tasks, lam = problem.tasks, discount
        self.starts, self.reach = [], []
        now, at = origin.time, self.home
        for j, row in zip(self.route, self.point):
            reach = now + self.times[at][row]
            start = max(reach, tasks[j].opens)
            self.reach.append(reach)
            self.starts.append(start)
            now, at = start + tasks[j].service, row
        # _weight[k]: Σ reward · λ^start over the first k tasks; _waits[k]: the first task at
        # or after k that waits for its arrival (len(route): none)
        self._weight = [0.0]
        for j, start in zip(self.route, self.starts):
            self._weight.append(self._weight[-1] + tasks[j].reward * lam ** start)
        self._waits = [len(self.route)] * (len(self.route) + 1)
        for k in range(len(self.route) - 1, -1, -1):
            self._waits[k] = k if self.starts[k] > self.reach[k] else self._waits[k + 1]
        # each place n's (row of `times` it leaves from, the time it is free there): what every
        # candidate's pass reads, computed once (`insertion` is CBBA's inner loop)
        self._places = [(self.home, origin.time)] + [
            (row, start + tasks[j].service)
            for row, start, j in zip(self.point, self.starts, self.route)]
        self._binding = binding(problem)

    def insertion(self, j: int) -> tuple[float, int]:
        """(marginal score, place) of task j at its best place; the earliest place on ties."""
        tasks, lam, times = self.problem.tasks, self.discount, self.times
        row_j, arrival, service, reward = (len(self.problem.robots) + j, tasks[j].opens,
                                           tasks[j].service, tasks[j].reward)
        length = len(self.route)
        allowed = (windowed_places(self.problem, self.i, self.route, j, self.origin)
                   if self._binding else None)
        if allowed is not None and not allowed:
            return 0.0, 0  # nowhere its window holds: scores nothing (module docstring)
        from_j, point, reach, waits = times[row_j], self.point, self.reach, self._waits
        weight = self._weight
        total = weight[length]
        best, where = -math.inf, 0
        for n, (prev, free) in enumerate(self._places):
            if allowed is not None and n not in allowed:
                continue
            start = free + times[prev][row_j]
            if start < arrival:
                start = arrival
            gain = lam ** start * reward
            if n < length:
                delay = start + service + from_j[point[n]] - reach[n]
                if delay >= 0 and waits[n] == length:
                    # no task after n waits: the delay passes through them all (`_delay`'s
                    # first step, inlined; 0.0 + keeps its sum bit for bit)
                    gain += 0.0 + (lam ** delay - 1.0) * (total - weight[n])
                else:
                    gain += self._delay(n, delay)
            if gain > best:
                best, where = gain, n
        return best, where

    def _delay(self, k: int, delay: float) -> float:
        """The change of score when the task at place k is reached `delay` later."""
        tasks, lam, length = self.problem.tasks, self.discount, len(self.route)
        change = 0.0
        while k < length:
            if delay < 0:  # a distance matrix without the triangle inequality: follow exactly
                return change + self._exact(k, delay)
            nxt = self._waits[k]
            if nxt > k:  # tasks that do not wait: the delay passes through them unchanged
                change += (lam ** delay - 1.0) * (self._weight[nxt] - self._weight[k])
                k = nxt
                continue
            moved = max(self.reach[k] + delay, tasks[self.route[k]].opens)
            if moved == self.starts[k]:
                break  # the wait absorbed it: the rest of the route keeps its timing
            change += (lam ** moved - lam ** self.starts[k]) * tasks[self.route[k]].reward
            delay = moved - self.starts[k]
            k += 1
        return change

    def _exact(self, k: int, delay: float) -> float:
        tasks, lam = self.problem.tasks, self.discount
        change = 0.0
        for k in range(k, len(self.route)):
            moved = max(self.reach[k] + delay, tasks[self.route[k]].opens)
            if moved == self.starts[k]:
                break
            change += (lam ** moved - lam ** self.starts[k]) * tasks[self.route[k]].reward
            delay = moved - self.starts[k]
        return change


def prefix_scores(problem: Problem, i: int, bundle: Sequence[int], path: Sequence[int],
                  tasks: Sequence[int], discount: float, origin: Origin = Origin(),
                  diminishing: bool = True, times: list[list[float]] | None = None,
                  ) -> list[dict[int, tuple[float, int]]]:
    """For k = 0 … len(bundle): each task of `tasks` not among the bundle's first k, with its
    (score, best place) on the route of those first k tasks (`path` restricted to them: the
    route they made when they were the whole bundle). `diminishing`: the score is the least of
    the task's marginal scores on that route and every shorter one (docs/cbba.md, "Diminishing
    marginal gain"); otherwise its marginal score there."""
    levels: list[dict[int, tuple[float, int]]] = []
    floor = dict.fromkeys(tasks, math.inf)
    times = times if times is not None else travel_times(problem, i)
    for k in range(len(bundle) + 1):
        held = set(bundle[:k])
        route = DiscountedRoute(problem, i, [t for t in path if t in held], discount, origin,
                                times)
        level = {}
        for j in tasks:
            if j in held:
                continue
            score, where = route.insertion(j)
            if diminishing:
                floor[j] = score = min(floor[j], score)
            level[j] = (score, where)
        levels.append(level)
    return levels


def sequential_greedy(problem: Problem, discount: float, tasks: Sequence[int] | None = None,
                      limit: int | None = None, diminishing: bool = True,
                      routes: dict[int, list[int]] | None = None,
                      ) -> tuple[dict[int, list[int]], list[tuple[int, int, float]]]:
    """The sequential greedy algorithm (SGA; Choi et al. 2009, §IV-C) on the discounted score:
    repeatedly give the task of `tasks` (default: all) with the largest marginal score to the
    robot it has it for, inserted at its best place, until no task has a positive score, every
    task is given or every robot holds `limit` tasks. Ties: lower robot id, then lower task id.

    `diminishing`: a robot's score for a task is the least of its marginal scores over the
    robot's routes after each of its picks so far (CBBA's bid here: docs/cbba.md); False: the
    paper's marginal score. `routes`: routes to continue from (after a robot left, or tasks
    arrived), their tasks taken as picked in route order. Returns the routes (robot index → task
    indices in service order) and the picks in order (robot, task, score)."""
    n_robots = len(problem.robots)
    routes = {i: list(r) for i, r in (routes or {}).items()}
    for i in range(n_robots):
        routes.setdefault(i, [])
    left = set(range(len(problem.tasks)) if tasks is None else tasks)
    robot_rank = ranks([r.id for r in problem.robots])
    task_rank = ranks([t.id for t in problem.tasks])
    times = [travel_times(problem, i) for i in range(n_robots)]
    floors: dict[int, dict[int, float]] = {i: {} for i in range(n_robots)}
    if diminishing:  # continued routes: their tasks count as picked in route order
        for i in range(n_robots):
            for level in prefix_scores(problem, i, routes[i], routes[i], sorted(left),
                                       discount, times=times[i])[:-1]:
                for j, (score, _) in level.items():
                    floors[i][j] = min(score, floors[i].get(j, math.inf))
    scores: dict[int, dict[int, tuple[float, int]]] = {}  # robot → task → (raw score, place)
    picks: list[tuple[int, int, float]] = []
    while left:
        best = None
        for i in range(n_robots):
            if limit is not None and len(routes[i]) >= limit:
                continue
            if i not in scores:  # its route changed: score every task again
                route = DiscountedRoute(problem, i, routes[i], discount, times=times[i])
                scores[i] = {j: route.insertion(j) for j in left if problem.capable(i, j)}
            for j, (raw, where) in scores[i].items():
                if j not in left:
                    continue
                score = min(raw, floors[i].get(j, math.inf))
                key = (score, -robot_rank[i], -task_rank[j])
                if score > 0 and (best is None or key > best[0]):
                    best = (key, i, j, where)
        if best is None:
            break
        (score, _, _), i, j, where = best
        routes[i].insert(where, j)
        left.discard(j)
        if diminishing:
            for t, (raw, _) in scores[i].items():
                floors[i][t] = min(raw, floors[i].get(t, math.inf))
        del scores[i]
        picks.append((i, j, score))
    return routes, picks
