"""Single-task robots, single-robot tasks, instantaneous assignment (ST-SR-IA, Gerkey & Matarić
2004): an instance, its cost matrix, the optimal assignment and the greedy one MURDOCH makes.

Generic — no application, no architecture: an application (delivery) turns its configuration
into an `Instance` and its recording into the assignment it achieved, and compares the two here.

* **Cost model.** `cost[i][j]` is robot i's travel time to task j: the straight-line distance from
  its start to the task divided by its speed; ∞ when it lacks the task's capability. Straight
  line because the worlds this is used in are open (no wall between a start and a task), where
  the straight line *is* the shortest path; a world with obstacles would need path distances
  (a visibility graph) and this function is where they would go. Service time and arrival time
  add the same amount whoever serves the task, so they are not part of the cost.
* **IA.** Each robot serves at most one task and each task needs one robot: an assignment is a
  matching of the bipartite robots × tasks graph. The optimum is a minimum-cost matching among
  those of maximum cardinality (scipy's `linear_sum_assignment`, rectangular allowed: with more
  tasks than robots some stay unassigned, with more robots some stay idle).
* **Online.** Tasks arrive over time. The offline optimum *with hindsight* knows every arrival
  in advance; since costs do not depend on time under IA it is the same matching as above.
  MURDOCH's online rule (`greedy_online`) auctions each task when it arrives and gives it to the
  free capable robot with the highest utility; Kalyanasundaram & Pruhs (1993) show greedy
  online weighted matching reaches at least ⅓ of the offline maximum *utility*, the bound
  Gerkey & Matarić quote for MURDOCH. For *costs* there is no constant bound (greedy online
  min-cost matching is 2ⁿ − 1 competitive), which is why runs report cost optimality as well.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Sequence

import numpy as np
from scipy.optimize import linear_sum_assignment

from mrta_zenoh.errors import ConfigError


@dataclass(frozen=True)
class Robot:
    id: str
    start: tuple[float, float]
    speed: float                      # m/s: the speed it drives at (its commanded cap)
    capabilities: frozenset[str]


@dataclass(frozen=True)
class Task:
    id: str
    position: tuple[float, float]
    arrival: float = 0.0              # s: when it appears (0 in a static instance)
    service: float = 0.0              # s: how long a robot must stay at it
    capability: str = ""              # what a robot needs to serve it ("": nothing)


@dataclass(frozen=True)
class Instance:
    robots: tuple[Robot, ...]
    tasks: tuple[Task, ...]

    def __post_init__(self) -> None:
        for what, items in (("robot", self.robots), ("task", self.tasks)):
            ids = [x.id for x in items]
            dup = next((i for i in ids if ids.count(i) > 1), None)
            if dup is not None:
                raise ConfigError(f"{what} id {dup!r} appears twice in the instance")
        for r in self.robots:
            if not (math.isfinite(r.speed) and r.speed > 0):
                raise ConfigError(f"robot {r.id}: speed must be a finite number > 0, "
                                  f"got {r.speed!r}")
        for t in self.tasks:
            if not (math.isfinite(t.arrival) and t.arrival >= 0):
                raise ConfigError(f"task {t.id}: arrival must be ≥ 0, got {t.arrival!r}")
            if not (math.isfinite(t.service) and t.service >= 0):
                raise ConfigError(f"task {t.id}: service must be ≥ 0, got {t.service!r}")

    @property
    def online(self) -> bool:
        """Whether tasks arrive over time (some arrival after 0)."""
        return any(t.arrival > 0 for t in self.tasks)

    def robot_index(self, robot_id: str) -> int:
        return next(i for i, r in enumerate(self.robots) if r.id == robot_id)

    def task_index(self, task_id: str) -> int:
        return next(j for j, t in enumerate(self.tasks) if t.id == task_id)

    def capable(self, robot: Robot, task: Task) -> bool:
        return not task.capability or task.capability in robot.capabilities

    def cost_matrix(self) -> np.ndarray:
        """cost[i][j]: robot i's travel time to task j (s); ∞ when it cannot serve it."""
        cost = np.full((len(self.robots), len(self.tasks)), math.inf)
        for i, r in enumerate(self.robots):
            for j, t in enumerate(self.tasks):
                if self.capable(r, t):
                    cost[i, j] = travel_time(r, t)
        return cost


def travel_time(robot: Robot, task: Task) -> float:
    """Straight-line distance from the robot's start to the task, over its speed."""
    return math.hypot(task.position[0] - robot.start[0],
                      task.position[1] - robot.start[1]) / robot.speed


@dataclass(frozen=True)
class Assignment:
    """Robot index → task index pairs (each robot and each task at most once) and their cost."""

    pairs: tuple[tuple[int, int], ...]
    cost: float

    def by_task(self) -> dict[int, int]:
        return {j: i for i, j in self.pairs}


def assignment_cost(cost: np.ndarray, pairs: Sequence[tuple[int, int]]) -> float:
    return float(sum(cost[i, j] for i, j in pairs))


def optimal_assignment(cost: np.ndarray) -> Assignment:
    """The minimum-cost assignment among those serving as many tasks as possible.

    Infeasible pairs (∞) get a cost M larger than any feasible assignment's total, so a
    solution with fewer of them always wins; they are then dropped from the answer."""
    cost = np.asarray(cost, dtype=float)
    if cost.size == 0:
        return Assignment((), 0.0)
    finite = np.isfinite(cost)
    if np.any(cost[finite] < 0):
        raise ValueError("costs must be ≥ 0")
    big = float(cost[finite].sum()) + 1.0 if finite.any() else 1.0
    rows, cols = linear_sum_assignment(np.where(finite, cost, big))
    pairs = tuple(sorted((int(i), int(j)) for i, j in zip(rows, cols) if finite[i, j]))
    return Assignment(pairs, assignment_cost(cost, pairs))


def optimal_utility_assignment(utility: np.ndarray) -> tuple[tuple[tuple[int, int], ...], float]:
    """The maximum-utility assignment (−∞: infeasible); pairs and total utility. Only pairs of
    positive utility are kept (a negative one lowers the total)."""
    utility = np.asarray(utility, dtype=float)
    if utility.size == 0:
        return (), 0.0
    feasible = np.isfinite(utility) & (utility > 0)
    rows, cols = linear_sum_assignment(np.where(feasible, utility, 0.0), maximize=True)
    pairs = tuple(sorted((int(i), int(j)) for i, j in zip(rows, cols) if feasible[i, j]))
    return pairs, float(sum(utility[i, j] for i, j in pairs))


def greedy_online(utility: np.ndarray, arrivals: Sequence[float]) -> tuple[tuple[int, int], ...]:
    """MURDOCH's online assignment, simulated: tasks are auctioned when they arrive (those
    arriving together in one round, awarded greedily over the round as its auctioneer does);
    each goes to the free robot with the highest finite utility, ties to the lower robot index
    (then task index); an assigned robot stays assigned (IA). A task nobody can serve when it
    arrives stays unassigned."""
    utility = np.asarray(utility, dtype=float)
    n_robots, n_tasks = utility.shape
    free = set(range(n_robots))
    pairs: list[tuple[int, int]] = []
    for at in sorted(set(arrivals)):
        batch = [j for j in range(n_tasks) if arrivals[j] == at]
        bids = sorted((-utility[i, j], i, j) for j in batch for i in free
                      if math.isfinite(utility[i, j]))
        taken: set[int] = set()
        for _, i, j in bids:
            if i in free and j not in taken:
                free.discard(i)
                taken.add(j)
                pairs.append((i, j))
    return tuple(sorted(pairs))


def murdoch_utility(cost: np.ndarray, level: float = 1.0, weight: float = 0.01) -> np.ndarray:
    """MURDOCH's bid for each pair, as a delivery robot configured with skill `level` and
    distance_weight = `weight` / speed bids: level − weight · travel time (−∞: incapable)."""
    cost = np.asarray(cost, dtype=float)
    return np.where(np.isfinite(cost), level - weight * cost, -math.inf)


def poisson_arrivals(rng: np.random.Generator, rate: float, n: int) -> list[float]:
    """Arrival times of a Poisson process of `rate` tasks per second: n cumulative
    exponential gaps, rounded to the millisecond (times travel in messages and YAML)."""
    if not (math.isfinite(rate) and rate > 0):
        raise ValueError(f"arrival rate must be > 0, got {rate!r}")
    return [round(float(t), 3) for t in np.cumsum(rng.exponential(1.0 / rate, n))]


def random_instance(rng: np.random.Generator, n_robots: int, n_tasks: int, *,
                    size: tuple[float, float] = (12.0, 8.0), speeds: tuple[float, float] = (0.3, 0.7),
                    capabilities: Sequence[str] = ("", ), rate: float | None = None,
                    service: float = 5.0) -> Instance:
    """A random instance in a `size` rectangle centred on 0: starts and task positions uniform,
    speeds uniform in `speeds`, each task needing one of `capabilities` ("" = none) and each
    robot having each non-empty capability with probability ½ (at least one robot has every
    capability used, so every task is feasible). `rate` (tasks/s): Poisson arrivals (online);
    None: all at 0 (static)."""
    w, h = size

    def point() -> tuple[float, float]:
        return (round(float(rng.uniform(-w / 2, w / 2)), 3),
                round(float(rng.uniform(-h / 2, h / 2)), 3))

    caps = [c for c in capabilities if c]
    robots = []
    for i in range(n_robots):
        has = frozenset(c for c in caps if i == 0 or rng.random() < 0.5)
        robots.append(Robot(f"robot{i + 1}", point(),
                            round(float(rng.uniform(*speeds)), 3), has))
    arrivals = poisson_arrivals(rng, rate, n_tasks) if rate else [0.0] * n_tasks
    tasks = tuple(Task(f"t{j + 1}", point(), arrivals[j], service,
                       str(capabilities[int(rng.integers(len(capabilities)))]))
                  for j in range(n_tasks))
    return Instance(tuple(robots), tasks)
