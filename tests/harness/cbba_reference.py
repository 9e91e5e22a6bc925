"""CBBA's score, marginal score, sequential greedy algorithm and exact optimum, restated from
their definitions (Choi, Brunet & How 2009; docs/cbba.md) for the tests to check the code
against: nothing here uses mrta_zenoh.planning.insertion or mrta_agent.cbba."""

from __future__ import annotations

import itertools
import math
import random

from mrta_zenoh.planning import Problem, Robot, Task

LAMBDA = 0.95
TIE = 1e-12  # scores this close are equal: a wait for a task's arrival makes exact ties common,
#              and this file's arithmetic ((x + y) − x) differs from the logic's in the last bit


# ------------------------------------------------------------------ the definitions, restated
def score(p: Problem, i: int, route, lam: float = LAMBDA) -> float:
    """Σ λ^start · reward along robot i's route: travel = distance ÷ speed, service times, and a
    wait for a task not yet arrived (start = max(reach, arrival))."""
    n, t, at, total = len(p.robots), 0.0, i, 0.0
    for j in route:
        start = max(t + p.distance[at][n + j] / p.robots[i].speed, p.tasks[j].arrival)
        total += lam ** start * p.tasks[j].reward
        t, at = start + p.tasks[j].service, n + j
    return total


def marginal(p: Problem, i: int, route, j: int) -> tuple[float, int]:
    """The largest increase of the route's score over every place for j; the earliest place
    on ties."""
    base, best = score(p, i, route), None
    for pos in range(len(route) + 1):
        gain = score(p, i, route[:pos] + [j] + route[pos:]) - base
        if best is None or gain > best[0] + TIE:
            best = (gain, pos)
    return best


def greedy(p: Problem, robots=None, tasks=None, limit=None, diminishing=True):
    """SGA: repeatedly the (robot, task) of largest score — a robot's score for a task being
    its marginal score, lowered (`diminishing`) to the least it had after each of the robot's
    earlier picks — ties to the lower robot id, then the lower task id; until nothing scores
    above 0. Returns routes and picks (robot, task, score)."""
    robots = list(range(len(p.robots)) if robots is None else robots)
    robot_place = {r.id: k for k, r in enumerate(sorted(p.robots, key=lambda r: r.id))}
    task_place = {t.id: k for k, t in enumerate(sorted(p.tasks, key=lambda t: t.id))}
    routes = {i: [] for i in robots}
    floors = {i: {} for i in robots}
    left = set(range(len(p.tasks)) if tasks is None else tasks)
    picks = []
    while left:
        best, seen = None, {}
        for i in robots:
            if limit is not None and len(routes[i]) >= limit:
                continue
            for j in sorted(left):
                if not p.capable(i, j):
                    continue
                raw, pos = marginal(p, i, routes[i], j)
                seen[i, j] = raw
                value = min(raw, floors[i].get(j, math.inf)) if diminishing else raw
                ids = (robot_place[p.robots[i].id], task_place[p.tasks[j].id])
                if value > TIE and (best is None or value > best[0] + TIE
                                    or (value > best[0] - TIE and ids < best[1])):
                    best = (value, ids, i, j, pos)
        if best is None:
            break
        value, _, i, j, pos = best
        for (r, t), raw in seen.items():
            if r == i:
                floors[i][t] = min(raw, floors[i].get(t, math.inf))
        routes[i].insert(pos, j)
        left.discard(j)
        picks.append((i, j, value))
    return routes, picks


def optimum(p: Problem) -> float:
    """The largest total score over every assignment (tasks may stay unserved) and every order:
    each robot's best order for each set of tasks, then the best split of the tasks."""
    m = len(p.tasks)
    best_of = []
    for i in range(len(p.robots)):
        table = {}
        for mask in range(1 << m):
            tasks = [j for j in range(m) if mask >> j & 1]
            table[mask] = (max(score(p, i, list(order)) for order in itertools.permutations(tasks))
                           if all(p.capable(i, j) for j in tasks) else -math.inf)
        best_of.append(table)

    def subsets(mask):
        sub = mask
        while True:
            yield sub
            if sub == 0:
                return
            sub = (sub - 1) & mask

    value = [max(best_of[0][s] for s in subsets(mask)) for mask in range(1 << m)]
    for table in best_of[1:]:
        value = [max(table[s] + value[mask ^ s] for s in subsets(mask)) for mask in range(1 << m)]
    return value[-1]


def random_instance(rng: random.Random, n: int, m: int) -> Problem:
    timed = rng.random() < 0.5  # arrivals, services and rewards, or plain points
    robots = tuple(Robot(f"r{i}", (rng.uniform(0, 20), rng.uniform(0, 20)),
                         rng.uniform(0.5, 1.5),
                         frozenset({"lift"}) if rng.random() < 0.7 else frozenset())
                   for i in range(n))
    tasks = tuple(Task(f"t{j:02d}", (rng.uniform(0, 20), rng.uniform(0, 20)),
                       arrival=rng.uniform(0, 30) if timed else 0.0,
                       service=rng.uniform(0, 3) if timed else 0.0,
                       reward=rng.uniform(0.5, 2.0) if timed else 1.0,
                       capability="lift" if rng.random() < 0.2 else "") for j in range(m))
    return Problem(robots, tasks)
