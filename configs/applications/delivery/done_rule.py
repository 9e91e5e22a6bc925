"""When a robot's `done` is believed (issue 51): by its teammates' boards (board.py), by the
supervisor's task watch that ends a run once every task is done (mission.DeliveryWatch), and by
the analysis that counts deliveries (metrics.py, which also checks the simulator's ground truth).

A `done` counts only from the robot whose service it was: its sender said, on its own key,
`started` for the task — at a time it could have reached the task (from its start, at its
speed, not before the task arrived: `earliest`, less REACH_SLACK) — at least the task's service
before the `done`. A `done` heard before its `started` (the two keys may be delivered out of
order) waits and counts when the `started` comes. Four `done` from a robot that never moved
used to end the run at 3.3 s "every task done" with 0/4 delivered; each is now refused, counted
as forged (`done_not_started`), and leaves the task to be served. What the rule cannot tell: a
forger who says `started` and then `done` in a robot's name, each no earlier than that robot
could have said it (docs/security.md) — the analysis's ground-truth check still does not count
that delivery.

A task submitted at run time (not in the instance: mrta task submit) has no position or service
the rule knows: its `done` needs only its sender's `started` before it. Bounded: one entry per
(robot, task) of the instance, and at most MAX_OTHER tasks outside it; robots outside the
instance are ignored.
"""

from __future__ import annotations

import collections
import math
from typing import Mapping

from mrta_zenoh.clock import EPSILON
from mrta_zenoh.errors import ConfigError
from mrta_zenoh.planning.geometry import PathMap

from .instance import InstanceBody

REACH_SLACK = 2.0  # s: a robot stops within `tolerance` of a task, a little before reaching it
MAX_OTHER = 10_000  # tasks outside the instance (submitted at run time) the rule keeps track of

# why a delivery event was not believed (the receiver's refusal tally: kind "task_event")
NOT_STARTED = "done_not_started"    # a done without its sender's `started` a service before
TOO_EARLY = "started_too_early"     # a started before its sender could have reached the task
NOT_OWN = "own_done_not_said"       # a done on this robot's own key that it never said
KIND = "task_event"


class DoneRule:
    """The rule for one receiver (module docstring). Not thread-safe: its owner locks."""

    def __init__(self, instance: InstanceBody, paths: PathMap | None = None):
        """`paths`: the world's path map (None: an open room, straight lines), as the robot's
        delivery layers share it."""
        self.instance, self.paths = instance, paths
        self._earliest: dict[tuple[str, str], float] = {}
        self._other: set[str] = set()  # tasks heard of outside the instance (MAX_OTHER)
        self.started: dict[tuple[str, str], float] = {}   # earliest plausible `started`
        self.waiting: dict[tuple[str, str], float] = {}   # a `done` heard before its `started`
        self.refused: collections.Counter[tuple[str, str, str, bool]] = collections.Counter()

    def earliest(self, robot: str, task: str) -> float:
        """The earliest `robot` could have reached `task`: from its start at its speed (a
        shortest path), not before the task arrived."""
        key = (robot, task)
        if task not in self.instance.tasks:
            return -math.inf  # submitted at run time: where it is, the rule does not know
        if key not in self._earliest:
            r, t = self.instance.robots[robot], self.instance.tasks[task]
            a, b = (float(r.start[0]), float(r.start[1])), (float(t.position[0]),
                                                             float(t.position[1]))
            try:
                metres = self.paths.length(a, b) if self.paths is not None else math.dist(a, b)
            except ConfigError:  # walls close it off: it cannot be reached at all
                metres = math.inf
            self._earliest[key] = max(metres / r.speed, t.arrival)
        return self._earliest[key]

    def knows(self, robot: str, task: str) -> bool:
        if robot not in self.instance.robots:
            return False
        if task in self.instance.tasks or task in self._other:
            return True
        if len(self._other) >= MAX_OTHER:
            return False
        self._other.add(task)
        return True

    def on_started(self, robot: str, task: str, stamp: float) -> float | None:
        """A `started`; returns the stamp of a waiting `done` it makes believed (None: none)."""
        if not self.knows(robot, task):
            return None
        key = (robot, task)
        if stamp < self.earliest(robot, task) - REACH_SLACK:
            self.refused[(KIND, robot, TOO_EARLY, True)] += 1
            return None
        if stamp < self.started.get(key, math.inf):
            self.started[key] = stamp
        done = self.waiting.get(key)
        if done is not None and self._served(key, done):
            del self.waiting[key]
            self._unrefuse((KIND, robot, NOT_STARTED, True))
            return done
        return None

    def on_done(self, robot: str, task: str, stamp: float) -> bool:
        """A `done`: whether it is believed now. One not believed waits for its `started`, and
        is counted as refused until that comes (once per robot and task)."""
        if not self.knows(robot, task):
            return False
        key = (robot, task)
        if self._served(key, stamp):
            return True
        if key not in self.waiting:
            self.waiting[key] = stamp
            self.refused[(KIND, robot, NOT_STARTED, True)] += 1
        return False

    def _served(self, key: tuple[str, str], done: float) -> bool:
        started = self.started.get(key)
        spec = self.instance.tasks.get(key[1])
        service = spec.service if spec is not None else 0.0
        return started is not None and done >= started + service - EPSILON

    def _unrefuse(self, entry: tuple[str, str, str, bool]) -> None:
        self.refused[entry] -= 1
        if self.refused[entry] <= 0:
            del self.refused[entry]

    def refusals(self) -> Mapping[tuple[str, str, str, bool], int]:
        return dict(self.refused)
