"""The ST-SR-TA problem every delivery-like mission poses, as planners and architectures read it:
robots (start, speed, capabilities), point tasks (position, arrival, service time, capability,
reward, time window) and the travel-time model between any two of their points.

Generic — no application, no architecture: the delivery application builds a `Problem` from its
instance document; `central`, `ssi` and `cbba` plan on one; the mission's analysis evaluates the
order robots actually served their tasks on one (`schedule.py`). Pure Python, no numpy: a
robot's agent builds one at start, and an agent must stay small (numpy alone is ≈ 14 MB of RSS).

Travel model: the robot-independent *distance* between points (straight lines in an open world,
shortest paths around walls otherwise — `distances` is whatever the instance's world gives),
divided by the robot's own speed. Points are indexed robots' starts first, then tasks, so
`distance[i][n_robots + j]` is robot i's start to task j.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass, field
from enum import Enum
from typing import Callable, Sequence

from ..errors import ConfigError

Point = tuple[float, float]


@dataclass(frozen=True)
class Robot:
    id: str
    start: Point
    speed: float                          # m/s: the speed it drives at (its commanded cap)
    capabilities: frozenset[str] = frozenset()
    # when it leaves its start (s): 0 for a fresh robot; a re-planning dispatcher gives a robot
    # the completion of the tasks it is committed to, its start being the last of them
    ready: float = 0.0
    capacity: int | None = None           # tasks it may serve at most (None: unlimited)


@dataclass(frozen=True)
class Task:
    id: str
    position: Point
    arrival: float = 0.0                  # s: when it appears (0: known from the start)
    service: float = 0.0                  # s: how long a robot must stay at it
    capability: str = ""                  # what a robot needs to serve it ("": nothing)
    reward: float = 1.0                   # what serving it is worth (CBBA's score)
    # its time window (docs/delivery.md, "Time windows"): service may not start before
    # `earliest` (a robot there sooner waits) and must start by `due` (inf: no due)
    earliest: float = 0.0
    due: float = math.inf

    @property
    def windowed(self) -> bool:
        return self.earliest > 0 or math.isfinite(self.due)

    @property
    def opens(self) -> float:
        """The earliest its service may start: after it arrived and its window opened."""
        return max(self.arrival, self.earliest)


class Windows(str, Enum):
    """How a due binds (docs/delivery.md, "Time windows"): `hard` — a task not started by its
    due is missed (not served); `soft` — it is served late and its lateness counted."""

    HARD = "hard"
    SOFT = "soft"


def straight_line(a: Point, b: Point) -> float:
    return math.hypot(b[0] - a[0], b[1] - a[1])


@dataclass(frozen=True)
class Problem:
    """An instance as planners see it. `distance` is the (n_robots + n_tasks)² matrix of path
    lengths between points (starts, then tasks), straight lines when not given."""

    robots: tuple[Robot, ...]
    tasks: tuple[Task, ...]
    distance: tuple[tuple[float, ...], ...] = field(default=(), repr=False)
    windows: Windows = Windows.HARD       # how every task's due binds

    def __post_init__(self) -> None:
        for what, items in (("robot", self.robots), ("task", self.tasks)):
            seen: set[str] = set()
            for x in items:
                if x.id in seen:
                    raise ConfigError(f"{what} id {x.id!r} appears twice in the instance")
                seen.add(x.id)
        for r in self.robots:
            if not (math.isfinite(r.speed) and r.speed > 0):
                raise ConfigError(f"robot {r.id}: speed must be a finite number > 0, "
                                  f"got {r.speed!r}")
            if not (math.isfinite(r.ready) and r.ready >= 0):
                raise ConfigError(f"robot {r.id}: ready must be ≥ 0, got {r.ready!r}")
            if r.capacity is not None and r.capacity < 0:
                raise ConfigError(f"robot {r.id}: capacity must be ≥ 0, got {r.capacity!r}")
        for t in self.tasks:
            for name in ("arrival", "service"):
                value = getattr(t, name)
                if not (math.isfinite(value) and value >= 0):
                    raise ConfigError(f"task {t.id}: {name} must be ≥ 0, got {value!r}")
            if not (math.isfinite(t.earliest) and t.earliest >= 0):
                raise ConfigError(f"task {t.id}: earliest must be ≥ 0, got {t.earliest!r}")
            if not t.due >= t.opens:  # NaN too
                raise ConfigError(f"task {t.id}: due ({t.due!r}) must be ≥ its arrival and "
                                  f"earliest ({t.opens!r}): it could never be started")
            if not math.isfinite(t.reward):
                raise ConfigError(f"task {t.id}: reward must be a finite number, got {t.reward!r}")
        object.__setattr__(self, "windows", Windows(self.windows))
        n = len(self.robots) + len(self.tasks)
        if not self.distance:
            points = self.points
            object.__setattr__(self, "distance", tuple(
                tuple(straight_line(a, b) for b in points) for a in points))
        elif len(self.distance) != n or any(len(row) != n for row in self.distance):
            raise ConfigError(f"the distance matrix must be {n} × {n} (robots' starts, then "
                              "tasks)")

    @classmethod
    def with_paths(cls, robots: Sequence[Robot], tasks: Sequence[Task],
                   path: Callable[[Point, Point], float]) -> "Problem":
        """A problem whose distances come from `path(a, b)` (e.g. shortest paths around walls)."""
        points = [r.start for r in robots] + [t.position for t in tasks]
        return cls(tuple(robots), tuple(tasks),
                   tuple(tuple(path(a, b) for b in points) for a in points))

    @property
    def points(self) -> list[Point]:
        return [r.start for r in self.robots] + [t.position for t in self.tasks]

    @property
    def online(self) -> bool:
        """Whether some task arrives after the start."""
        return any(t.arrival > 0 for t in self.tasks)

    @functools.cached_property
    def windowed(self) -> bool:
        """Whether some task has a time window (an earliest start or a due). Remembered (the
        problem is frozen): every insertion asks, and at 100 tasks asking anew was ≈ 45 % of a
        CBBA robot's first bundle (benchmarks/README.md, agent hosts)."""
        return any(t.windowed for t in self.tasks)

    @functools.cached_property
    def _indices(self) -> tuple[dict[str, int], dict[str, int]]:
        """Robots' and tasks' indices by id, made once: a dispatcher planning a burst of 200
        tasks looked each up thousands of times a re-plan, by a scan."""
        return ({r.id: i for i, r in enumerate(self.robots)},
                {t.id: j for j, t in enumerate(self.tasks)})

    def robot_index(self, robot_id: str) -> int:
        i = self._indices[0].get(robot_id)
        if i is None:
            raise KeyError(robot_id)
        return i

    def task_index(self, task_id: str) -> int:
        j = self._indices[1].get(task_id)
        if j is None:
            raise KeyError(task_id)
        return j

    def capable(self, i: int, j: int) -> bool:
        need = self.tasks[j].capability
        return not need or need in self.robots[i].capabilities

    def travel(self, i: int, src: int | None, j: int) -> float:
        """Robot i's travel time to task j from task `src` (None: from its start)."""
        a = i if src is None else len(self.robots) + src
        return self.distance[a][len(self.robots) + j] / self.robots[i].speed

    def grown(self, tasks: Sequence[Task],
              path: Callable[[Point, Point], float] | None = None) -> "Problem":
        """The same problem with `tasks` appended (tasks submitted at run time): every index
        before keeps its meaning, the distances known are kept and only the new rows and
        columns computed, by `path(a, b)` (None: straight lines)."""
        path = path or straight_line
        n = len(self.robots) + len(self.tasks)
        points = self.points + [t.position for t in tasks]
        rows = [list(row) + [path(points[a], p) for p in points[n:]]
                for a, row in enumerate(self.distance)]
        rows += [[path(q, p) for p in points] for q in points[n:]]
        for b in range(n, len(points)):  # symmetric, as PathMap.matrix is
            for a in range(n):
                rows[b][a] = rows[a][b]
        return Problem(self.robots, self.tasks + tuple(tasks),
                       tuple(tuple(row) for row in rows), self.windows)

    def restricted(self, task_ids: Sequence[str]) -> "Problem":
        """The same robots with only `task_ids` (in that order), distances kept: what a
        planner re-solves when some tasks are done or not yet known."""
        n = len(self.robots)
        keep = list(range(n)) + [n + self.task_index(t) for t in task_ids]
        return Problem(self.robots, tuple(self.tasks[k - n] for k in keep[n:]),
                       tuple(tuple(self.distance[a][b] for b in keep) for a in keep),
                       self.windows)
