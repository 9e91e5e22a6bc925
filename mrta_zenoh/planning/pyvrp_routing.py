"""Best-found MinSum routes by PyVRP (Wouters et al., "PyVRP: a high-performance VRP solver
package", INFORMS J. Computing 2024; its hybrid genetic search won the VRPTW track of the DIMACS
2021 implementation challenge), for comparison with OR-Tools (routing.py) on the same problems
(`benchmarks/windows_reference.py`, benchmarks/README.md "Reference under time windows").

The model maps onto PyVRP's documented features: each robot is a vehicle type of its own (one
available) leaving its start depot at its `ready` time on a routing profile of its own — its
travel times (ms) as both distance and duration, so PyVRP's distance objective is MinSum's
travel time; no edge into a task it lacks the capability for (PyVRP's missing edge, a huge
value); tasks are clients with service duration and the time window [max(arrival, earliest),
due]; every vehicle ends at one dummy depot reached from anywhere at no cost (open routes, as
the objectives define). Under binding hard windows (`exact.binding`) a task is optional with a
prize larger than any set of routes' travel (n + 1 times the longest leg: a prize
far larger still, 10¹², left PyVRP's penalty search in infeasible routes), so the search serves the most tasks it can
before it lowers travel — the hierarchical reference. A robot's task capacity is a load of 1
per task. Makespan and flowtime are not PyVRP objectives: OR-Tools alone solves those.

Deterministic for a fixed `seed` and iteration count (`iterations`); `time_limit` is a safety
cap that, when it stops the search, makes the result machine-dependent (`capped`). Routes are
checked again in floats (routing._keep_in_windows), as OR-Tools' are.
"""

from __future__ import annotations

import math
import time

from ..errors import ConfigError
from .exact import binding
from .problem import Problem
from .routing import SCALE, BestFound, _keep_in_windows
from .schedule import Objective



def solve_pyvrp(problem: Problem, objective: Objective | str = Objective.MINSUM, *,
                iterations: int = 2000, time_limit: float = 30.0, seed: int = 0) -> BestFound:
    """PyVRP's best MinSum routes (ConfigError for another objective, or a task nobody can
    serve when windows do not bind)."""
    from pyvrp import Model
    from pyvrp.stop import MaxIterations, MaxRuntime, MultipleCriteria

    if Objective(objective) is not Objective.MINSUM:
        raise ConfigError(f"PyVRP minimises travel (MinSum) only, not {objective}")
    m, n = len(problem.robots), len(problem.tasks)
    if m == 0 or n == 0:
        return BestFound({i: [] for i in range(m)}, False)
    hard = binding(problem)
    if not hard:
        for j in range(n):
            if not any(problem.capable(i, j) for i in range(m)):
                raise ConfigError(f"task {problem.tasks[j].id}: no robot has capability "
                                  f"{problem.tasks[j].capability!r}")
    model = Model()
    homes = [model.add_location(*r.start) for r in problem.robots]
    places = [model.add_location(*t.position) for t in problem.tasks]
    nowhere = model.add_location(0.0, 0.0)
    starts = [model.add_depot(home, tw_early=round(r.ready * SCALE))
              for home, r in zip(homes, problem.robots)]
    end = model.add_depot(nowhere)
    limited = any(r.capacity is not None for r in problem.robots)
    prize = (n + 1) * max(round(problem.travel(i, src, j) * SCALE) + 1 for i in range(m)
                          for src in [None, *range(n)] for j in range(n))
    for place, t in zip(places, problem.tasks):
        model.add_client(
            place, delivery=[1] if limited else [],
            service_duration=round(t.service * SCALE), tw_early=round(t.opens * SCALE),
            tw_late=round(t.due * SCALE) if math.isfinite(t.due) else 2 ** 62,
            required=not hard, prize=prize if hard else 0)
    for i, robot in enumerate(problem.robots):
        profile = model.add_profile()
        model.add_vehicle_type(1, capacity=[robot.capacity if robot.capacity is not None else n]
                               if limited else [], start_depot=starts[i], end_depot=end,
                               profile=profile)
        for a, src in [(homes[i], None)] + [(places[k], k) for k in range(n)]:
            model.add_edge(a, nowhere, 0, 0, profile=profile)
            for j in range(n):
                if j != src and problem.capable(i, j):
                    leg = round(problem.travel(i, src, j) * SCALE)
                    model.add_edge(a, places[j], leg, leg, profile=profile)
    t0 = time.perf_counter()
    result = model.solve(MultipleCriteria([MaxIterations(iterations), MaxRuntime(time_limit)]),
                         seed=seed, display=False)
    capped = time.perf_counter() - t0 >= 0.98 * time_limit
    if not result.is_feasible():
        raise ConfigError("PyVRP found no feasible routes")
    routes: dict[int, list[int]] = {i: [] for i in range(m)}
    for route in result.best.routes():
        routes[route.vehicle_type()] = [a.idx for a in route if a.is_client()]
    if hard:
        routes = _keep_in_windows(problem, routes)
    return BestFound(routes, capped)
