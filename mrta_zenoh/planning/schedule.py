"""Routes, their timing, the three objectives and the time-window counts, defined once
(docs/delivery.md, "Objectives" and "Time windows").

A robot's *route* is the order in which it serves its tasks. Along it, robot i leaves its start at
0 and, for each task j in turn:

* `reach`  = when it gets there: the previous task's completion (or 0) + travel time;
* `start`  = when service begins: `reach`, or the task's arrival or its window's `earliest` if
  that is later (it waits);
* `end`    = the task's **completion**: `start` + service time.

This is the offline model with hindsight (a robot may reach a task before it arrives and wait):
the reference values are computed on it, and so is the objective of a run, from the order in
which each robot actually served its tasks, so any run's objective can be recomputed from its
summary alone. Objectives (all in seconds):

* **MinSum** (`total_travel`): the sum of every leg's travel time — no return to the start;
* **makespan**: the last completion;
* **flowtime**: the sum of completions.

Time windows (`window_counts`, from any service starts — a route's timing here, or the starts a
run's allocation records show, so a summary's counts can be recomputed from its records):

* **served in window**: served, its service started within [earliest, due];
* **late** / **lateness**: served, started after its due / Σ of how long after (s) — under soft
  windows what lateness costs; under hard windows a late start is a violation (none expected);
* **early**: served, started before its earliest — a violation under either kind (robots wait);
* **missed**: not served, and its due passed by `end` (a run's end — a run that ends when
  nothing is left to serve may end at a missed task's due; a plan has none) — unless it was
  `withdrawn` (cancelled at run time: nobody was to serve it any more).

Starts are compared with `WINDOW_TOLERANCE` of slack: allocation records are rounded to the ms.

Pure Python (agents evaluate routes while they bid).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from enum import Enum
from typing import Collection, Mapping, Sequence

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
        start = max(reach, problem.tasks[j].opens)
        end = start + problem.tasks[j].service
        visits.append(Visit(i, j, leg, reach, start, end))
        now, at = end, j
    return visits


WINDOW_TOLERANCE = 1e-3  # s: the resolution of allocation records' times


@dataclass(frozen=True)
class WindowCounts:
    """How served tasks' starts sat in their windows (module docstring)."""

    served_in_window: int
    missed: int
    late: int
    lateness: float      # s
    early: int

    @property
    def violations(self) -> int:
        """Starts outside the window a hard window forbids (late or early)."""
        return self.late + self.early

    def to_json(self) -> dict[str, int | float]:
        return {"served_in_window": self.served_in_window, "missed": self.missed,
                "late": self.late, "lateness": round(self.lateness, 3), "early": self.early}


def window_counts(problem: Problem, starts: Mapping[int, float],
                  end: float = math.inf, withdrawn: Collection[int] = ()) -> WindowCounts:
    """The window counts of serving task j from `starts[j]` (task index → start of service; a
    task not in it was not served) as of `end`; `withdrawn`: tasks cancelled, never missed
    (module docstring)."""
    in_window = missed = late = early = 0
    lateness = 0.0
    for j, task in enumerate(problem.tasks):
        start = starts.get(j)
        if start is None:
            missed += math.isfinite(task.due) and task.due <= end and j not in withdrawn
        elif start < task.earliest - WINDOW_TOLERANCE:
            early += 1
        elif start > task.due + WINDOW_TOLERANCE:
            late += 1
            lateness += start - task.due
        else:
            in_window += 1
    return WindowCounts(in_window, missed, late, lateness, early)


@dataclass(frozen=True)
class Evaluation:
    visits: tuple[Visit, ...]          # every robot's, robot by robot in route order
    total_travel: float
    makespan: float
    flowtime: float
    served: int
    windows: WindowCounts              # tasks off every route count as missed if they have a due

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
                      sum(v.end for v in visits), len(visits),
                      window_counts(problem, {v.task: v.start for v in visits}))


def routes_by_id(problem: Problem, routes: Mapping[str, Sequence[str]]) -> dict[int, list[int]]:
    """Routes named by robot and task ids → by indices (KeyError naming an unknown id)."""
    return {problem.robot_index(r): [problem.task_index(t) for t in route]
            for r, route in routes.items()}
