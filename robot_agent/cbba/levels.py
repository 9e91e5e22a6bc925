"""A bundle's prefix scores (`planning.insertion.prefix_scores`), computed only where CBBA's
greedy choice reads them.

Level k is the bundle's first k tasks, served in the order the path gives them; a task's score
on level k is its marginal score on that route, made diminishing (the least over levels 0 … k:
docs/cbba.md, "Diminishing marginal gain"). The bundle construction needs, on each level, only
the task with the largest score among those that outbid what this robot knows of them — and a
diminishing score on level k is at most the one on any earlier level. So a task's score
computed on some level bounds it on every later one, and the choice is made best bound first
(Minoux's lazy greedy): a task is scored on a level only while its bound could still win there.
A task whose bound cannot outbid its winner's bid, or that scores 0, is never scored further
on that level — at 100 robots × 100 tasks that is most of them once the first consensus round
has named winners. The scores computed are those eager computation gives, float for float (the
same routes, the same `DiscountedRoute.insertion`, the same least), so the choice is the same;
without `diminishing` there is no bound and every candidate is scored.
"""

from __future__ import annotations

import heapq
import math
from typing import Callable, Iterable, Sequence

from mrta_zenoh.planning import Problem
from mrta_zenoh.planning.insertion import DiscountedRoute, Origin

Score = tuple[float, int]  # (score, best place in the level's route)


class Levels:
    """The levels of one bundle, from its robot's `origin`. `plan()` gives the robot's bundle
    and path as they are now, read when a level's route is first needed: a level's route is
    the path restricted to the bundle's first k tasks, which neither growing nor cutting the
    bundle's end changes."""

    def __init__(self, problem: Problem, i: int, discount: float, origin: Origin,
                 times: list[list[float]], diminishing: bool,
                 plan: Callable[[], tuple[list[int], list[int]]]):
        self.problem, self.i, self.discount, self.origin = problem, i, discount, origin
        self.times, self.diminishing, self.plan = times, diminishing, plan
        self.routes: list[DiscountedRoute | None] = [None] * (len(plan()[0]) + 1)
        self.scores: dict[int, list[Score]] = {}  # task → its scores on levels 0, 1, …

    def __len__(self) -> int:
        return len(self.routes)

    def know(self, tasks: Iterable[int]) -> None:
        """Tasks to score from now on (on demand)."""
        for j in tasks:
            self.scores.setdefault(j, [])

    def known(self, j: int) -> bool:
        return j in self.scores

    def grown(self) -> None:
        """The bundle gained a task at its end: one level more."""
        self.routes.append(None)

    def cut(self, n: int) -> None:
        """The bundle was cut to its first n tasks: levels 0 … n stay what they were."""
        del self.routes[n + 1:]
        for done in self.scores.values():
            del done[n + 1:]

    def score(self, j: int, k: int) -> Score:
        """Task j's (score, place) on level k (j not among the bundle's first k tasks)."""
        done = self.scores[j]
        while len(done) <= k:
            raw, where = self._route(len(done)).insertion(j)
            if self.diminishing:
                raw = min(done[-1][0] if done else math.inf, raw)
            done.append((raw, where))
        return done[k]

    def bound(self, j: int, k: int) -> float:
        """An upper bound of task j's score on level k: its score there if computed, else its
        latest (a diminishing score only falls), else ∞."""
        done = self.scores[j]
        if len(done) > k:
            return done[k][0]
        if not self.diminishing:
            return self.score(j, k)[0]
        return done[-1][0] if done else math.inf

    def best(self, k: int, tasks: Iterable[int], outbids: Callable[[int, float], bool],
             rank: Sequence[int]) -> tuple[float, int, int] | None:
        """(score, task, place) of the task of `tasks` with the largest score on level k that
        scores above 0 and `outbids(task, score)` (which only a larger score can turn true),
        ties to the lower `rank`; None if there is none."""
        heap = []
        for j in tasks:
            ub = self.bound(j, k)
            if ub > 0 and outbids(j, ub):
                heap.append((-ub, rank[j], j))
        heapq.heapify(heap)
        while heap:
            neg, r, j = heap[0]
            score, where = self.score(j, k)
            if score == -neg:
                return score, j, where
            heapq.heappop(heap)
            if score > 0 and outbids(j, score):
                heapq.heappush(heap, (-score, r, j))
        return None

    def _route(self, k: int) -> DiscountedRoute:
        route = self.routes[k]
        if route is None:
            bundle, path = self.plan()
            held = set(bundle[:k])
            route = self.routes[k] = DiscountedRoute(
                self.problem, self.i, [t for t in path if t in held], self.discount,
                self.origin, self.times)
        return route
