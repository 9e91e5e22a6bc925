"""Routes, their timing and the three objectives, defined once (docs/delivery.md, "Objectives").

A robot's *route* is the order in which it serves its tasks. Along it, robot i leaves its start at
0 and, for each task j in turn:

* `reach`  = when it gets there: the previous task's completion (or 0) + travel time;
* `start`  = when service begins: `reach`, or the task's arrival if that is later (it waits);
* `end`    = the task's **completion**: `start` + service time.

This is the offline model with hindsight (a robot may reach a task before it arrives and wait):
the reference values are computed on it, and so is the objective of a run, from the order in
which each robot actually served its tasks, so any run's objective can be recomputed from its
summary alone. Objectives (all in seconds):

* **MinSum** (`total_travel`): the sum of every leg's travel time — no return to the start;
* **makespan**: the last completion;
* **flowtime**: the sum of completions.

Pure Python (agents evaluate routes while they bid).
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import Enum
from typing import Mapping, Sequence

from ..errors import ConfigError
from .problem import Problem


class Objective(str, Enum):
    MINSUM = "minsum"
    MAKESPAN = "makespan"
    FLOWTIME = "flowtime"


@dataclass(frozen=True)
class Visit:
    robot: int
    task: int
    travel: float   # the leg's travel time
    reach: float
    start: float
    end: float      # completion


def route_visits(problem: Problem, i: int, route: Sequence[int]) -> list[Visit]:
    """The timing of robot i serving `route` (task indices) in order, from its start at its
    `ready` time (0 unless a planner re-solving mid-run set it)."""
    visits: list[Visit] = []
    now, at = problem.robots[i].ready, None
    for j in route:
        leg = problem.travel(i, at, j)
        reach = now + leg
        start = max(reach, problem.tasks[j].arrival)
        end = start + problem.tasks[j].service
        visits.append(Visit(i, j, leg, reach, start, end))
        now, at = end, j
    return visits


@dataclass(frozen=True)
class Evaluation:
    visits: tuple[Visit, ...]          # every robot's, robot by robot in route order
    total_travel: float
    makespan: float
    flowtime: float
    served: int

    def value(self, objective: Objective | str) -> float:
        objective = Objective(objective)
        if objective is Objective.MINSUM:
            return self.total_travel
        if objective is Objective.MAKESPAN:
            return self.makespan
        return self.flowtime


def check_routes(problem: Problem, routes: Mapping[int, Sequence[int]]) -> None:
    """ConfigError unless every task appears at most once, on a robot able to serve it, and no
    robot serves more than its capacity."""
    seen: dict[int, int] = {}
    for i, route in routes.items():
        if not 0 <= i < len(problem.robots):
            raise ConfigError(f"routes name robot index {i}, not in the instance")
        cap = problem.robots[i].capacity
        if cap is not None and len(route) > cap:
            raise ConfigError(f"robot {problem.robots[i].id} serves {len(route)} tasks, more "
                              f"than its {cap}")
        for j in route:
            if not 0 <= j < len(problem.tasks):
                raise ConfigError(f"robot {problem.robots[i].id}'s route names task index {j}")
            if j in seen:
                raise ConfigError(f"task {problem.tasks[j].id} is on the routes of "
                                  f"{problem.robots[seen[j]].id} and {problem.robots[i].id}")
            if not problem.capable(i, j):
                raise ConfigError(f"robot {problem.robots[i].id} cannot serve task "
                                  f"{problem.tasks[j].id} (it needs "
                                  f"{problem.tasks[j].capability!r})")
            seen[j] = i


def evaluate(problem: Problem, routes: Mapping[int, Sequence[int]]) -> Evaluation:
    """The timing and objectives of `routes` (robot index → task indices in service order)."""
    check_routes(problem, routes)
    visits = [v for i in sorted(routes) for v in route_visits(problem, i, routes[i])]
    return Evaluation(tuple(visits), sum(v.travel for v in visits),
                      max((v.end for v in visits), default=0.0),
                      sum(v.end for v in visits), len(visits))


def routes_by_id(problem: Problem, routes: Mapping[str, Sequence[str]]) -> dict[int, list[int]]:
    """Routes named by robot and task ids → by indices (KeyError naming an unknown id)."""
    return {problem.robot_index(r): [problem.task_index(t) for t in route]
            for r, route in routes.items()}
