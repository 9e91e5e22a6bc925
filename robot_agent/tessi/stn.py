"""A robot's schedule as a simple temporal network (STN; Dechter, Meiri & Pearl, "Temporal
constraint networks", AI 49, 1991), as TeSSI keeps it (Nunes & Gini, AAAI 2015): every task of
the robot's path has a start time point bounded by its window [max(arrival, earliest), due],
its finish is its start plus its service, and the next task starts no sooner than that finish
plus the travel between them. The network is consistent when every start can be chosen inside
its bounds; its minimal form gives each task's *earliest* and *latest* start.

Why two passes and not Floyd–Warshall. The paper keeps the STN's distance graph and checks it
with all-pairs shortest paths. A robot's schedule is a total order (one robot serves one task at
a time, in the path's order), so its distance graph is a chain with window edges to the origin;
there the minimal network is one forward pass (earliest start = max(its opening, the previous
finish + travel)) and one backward pass (latest start = min(its due, the next latest start −
travel − service)), and the network is consistent iff earliest ≤ latest at every task — the
same answer in O(n) instead of O(n³).

Inserting task j before place n (`insertion`) is allowed only if the network stays consistent:
j's earliest start (after the task before it) is within its due, and the task after it is then
reached by its latest start (which already accounts for everything after it); the rest of the
network needs no check. Among the consistent places, the bid is the schedule's makespan with
j inserted — when its last task finishes at the earliest, on the run's clock (TeSSI: "the
makespan of the resulting simple temporal network is used to bid", Nunes & Gini 2015, abstract)
— or `weight` · that makespan + (1 − weight) · the travel j adds (TeSSIduo's combination with
distance, as the ROPOD project's public TeSSIduo implements it: α · makespan + (1 − α) · the
increase of the travel cost); ties to the earliest place. Not the makespan's *increase*: within
one robot both pick the same place, but across robots the makespan itself favours the robot
that finishes earliest (TeSSI's team objective, the time the last robot finishes) where the
increase would favour the one the task delays least (docs/tessi.md).

Under soft windows a due binds nothing (a late start is counted, not forbidden): the latest
starts are then infinite and every place is consistent.

Pure Python, on the planning model's travel times (mrta_zenoh.planning.problem).
"""

from __future__ import annotations

import math
from typing import Sequence

from mrta_zenoh.planning import Problem
from mrta_zenoh.planning.insertion import Origin
from mrta_zenoh.planning.problem import Windows


class Schedule:
    """Robot i's path from `origin` (its last task served and when it was free, or its start
    and its departure) as an STN: `earliest[k]`, `latest[k]` — the bounds of the start of the
    path's k-th task in the network's minimal form."""

    def __init__(self, problem: Problem, i: int, path: Sequence[int], origin: Origin = Origin()):
        self.problem, self.i, self.path, self.origin = problem, i, list(path), origin
        tasks = problem.tasks
        hard = problem.windows is Windows.HARD
        self.due = [tasks[j].due if hard else math.inf for j in self.path]
        self.earliest: list[float] = []
        self.finish: list[float] = []
        self.legs: list[float] = []
        now, at = origin.time, origin.task
        for j in self.path:
            leg = problem.travel(i, at, j)
            start = max(now + leg, tasks[j].opens)
            self.legs.append(leg)
            self.earliest.append(start)
            now, at = start + tasks[j].service, j
            self.finish.append(now)
        self.latest = [math.inf] * len(self.path)
        later = math.inf
        for k in range(len(self.path) - 1, -1, -1):
            j = self.path[k]
            if k + 1 < len(self.path):
                later -= problem.travel(i, j, self.path[k + 1]) + tasks[j].service
            later = min(self.due[k], later)
            self.latest[k] = later

    @property
    def consistent(self) -> bool:
        return all(e <= l for e, l in zip(self.earliest, self.latest))

    @property
    def makespan(self) -> float:
        """When the schedule's last task finishes at the earliest (its origin's time if
        empty)."""
        return self.finish[-1] if self.finish else self.origin.time

    @property
    def travel(self) -> float:
        return sum(self.legs)

    def insertion(self, j: int, weight: float = 1.0) -> tuple[float, int]:
        """(bid, place) of task j at its best consistent place (place n: before path[n]); the
        bid is weight · the makespan with j inserted + (1 − weight) · the travel j adds (module
        docstring). (inf, len(path)) when no place keeps the network consistent."""
        problem, i, path, task = self.problem, self.i, self.path, self.problem.tasks[j]
        due = task.due if problem.windows is Windows.HARD else math.inf
        best, where = math.inf, len(path)
        for n in range(len(path) + 1):
            prev = self.origin.task if n == 0 else path[n - 1]
            free = self.origin.time if n == 0 else self.finish[n - 1]
            to_j = problem.travel(i, prev, j)
            start = max(free + to_j, task.opens)
            if start > due:
                continue
            end = start + task.service
            if n < len(path):
                from_j = problem.travel(i, j, path[n])
                if end + from_j > self.latest[n]:
                    continue
                added_travel = to_j + from_j - self.legs[n]
                makespan = self._shifted(n, end + from_j)
            else:
                added_travel, makespan = to_j, end
            bid = weight * makespan + (1.0 - weight) * added_travel
            bid = max(bid, 0.0)  # ≥ 0 but for rounding: SSI refuses a negative bid
            if bid < best:
                best, where = bid, n
        return best, where

    def _shifted(self, k: int, reach: float) -> float:
        """The makespan when path[k] is reached at `reach` (the tasks after it follow; a wait
        for an opening absorbs a delay)."""
        tasks, path = self.problem.tasks, self.path
        for m in range(k, len(path)):
            start = max(reach, tasks[path[m]].opens)
            if start == self.earliest[m]:
                return self.makespan  # the delay is absorbed: the rest keeps its timing
            end = start + tasks[path[m]].service
            if m + 1 < len(path):
                reach = end + self.legs[m + 1]
        return end
