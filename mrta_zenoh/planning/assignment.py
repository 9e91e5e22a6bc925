"""Instantaneous assignment (ST-SR-IA, Gerkey & Matarić 2004): each robot serves at most one
task and each task needs one robot. The optimal assignment, and the greedy one MURDOCH makes.

Generic — no application, no architecture: an application builds a `Problem` from its instance
and compares the assignment its run achieved with these.

* **Cost.** `ia_costs(problem)[i][j]` is robot i's travel time from its start to task j: the
  problem's distance (straight line in an open world, the shortest drivable path around walls
  otherwise: `geometry.py`) over the robot's speed; ∞ when it lacks the task's capability.
  Service and arrival times add the same amount whoever serves the task, so under IA they are
  not part of the cost.
* **IA.** An assignment is a matching of the bipartite robots × tasks graph. The optimum is a
  minimum-cost matching among those of maximum cardinality (scipy's `linear_sum_assignment`,
  rectangular allowed: with more tasks than robots some stay unassigned, with more robots some
  stay idle).
* **Online.** Tasks arrive over time. The offline optimum *with hindsight* knows every arrival
  in advance; since costs do not depend on time under IA it is the same matching as above.
  MURDOCH's online rule (`greedy_online`) auctions each task when it arrives and gives it to the
  free capable robot with the highest utility; Kalyanasundaram & Pruhs (1993) show greedy
  online weighted matching reaches at least ⅓ of the offline maximum *utility*, the bound
  Gerkey & Matarić quote for MURDOCH. For *costs* there is no constant bound (greedy online
  min-cost matching is 2ⁿ − 1 competitive), which is why runs report cost optimality as well.

numpy and scipy: imported by whoever compares a run with the optimum, never by an agent. With
`$MRTA_REFERENCE_CACHE` (reference.py: the runs of an experiment's instance share one) the
optimum's pairs are solved once per cost matrix and read back by the other runs: importing
scipy.optimize was about a quarter of a 5 / 5 study run's runner (≈ 0.7 CPU-s), for a
matching the instance's first run had already made (benchmarks/README.md, "The study's runs").
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass
from pathlib import Path
from typing import Sequence

import numpy as np

from ..sha import sha256
from .problem import Problem
from .reference import REFERENCE_CACHE_ENV, cache_entry


def ia_costs(problem: Problem) -> np.ndarray:
    """cost[i][j]: robot i's travel time from its start to task j (s); ∞ when it cannot serve
    it."""
    cost = np.full((len(problem.robots), len(problem.tasks)), math.inf)
    for i in range(len(problem.robots)):
        for j in range(len(problem.tasks)):
            if problem.capable(i, j):
                cost[i, j] = problem.travel(i, None, j)
    return cost


@dataclass(frozen=True)
class Assignment:
    """Robot index → task index pairs (each robot and each task at most once) and their cost."""

    pairs: tuple[tuple[int, int], ...]
    cost: float


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

    def solve() -> dict:
        from scipy.optimize import linear_sum_assignment  # ≈ 1 CPU-s to import: only here
        rows, cols = linear_sum_assignment(np.where(finite, cost, big))
        return {"pairs": sorted((int(i), int(j)) for i, j in zip(rows, cols) if finite[i, j])}

    folder = os.environ.get(REFERENCE_CACHE_ENV)
    key = "ia-" + sha256(repr(cost.shape).encode() + cost.tobytes()).hexdigest()[:32]
    found = cache_entry(Path(folder), key, solve) if folder else solve()
    pairs = tuple((int(i), int(j)) for i, j in found["pairs"])
    return Assignment(pairs, assignment_cost(cost, pairs))


def optimal_utility_assignment(utility: np.ndarray) -> tuple[tuple[tuple[int, int], ...], float]:
    """The maximum-utility assignment (−∞: infeasible); pairs and total utility. Only pairs of
    positive utility are kept (a negative one lowers the total)."""
    utility = np.asarray(utility, dtype=float)
    if utility.size == 0:
        return (), 0.0
    feasible = np.isfinite(utility) & (utility > 0)
    from scipy.optimize import linear_sum_assignment  # ≈ 1 CPU-s to import: only here
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
