"""The reference value a run is compared with: one entry point over the exact recursion
(`exact.py`, small problems: proven optimal) and the routing search (`routing.py`, larger ones:
best found, never called optimal).

    reference(problem, "makespan")  →  Reference(value, routes, method, proven_optimal, seconds)

`routes` (robot index → task indices in service order) evaluate to `value` through
`schedule.evaluate`: the value is always the routes' own, computed in floats by the one
definition of the objectives.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

from ..errors import ConfigError
from .problem import Problem
from .schedule import Objective, evaluate

EXACT = "exact"
BEST_FOUND = "best found"
EXACT_LIMIT = 10      # tasks: the exact recursion up to here (3 robots × 10 tasks: < 1 s)


@dataclass(frozen=True)
class Reference:
    value: float
    routes: dict[int, list[int]]
    method: str                   # EXACT or BEST_FOUND
    proven_optimal: bool
    seconds: float                # the solve's wall time (a measurement, never a criterion)
    objective: Objective = Objective.MINSUM
    capped: bool = False          # the routing search stopped on its time cap (machine-dependent)

    @property
    def label(self) -> str:
        """What to call the value: "optimal" only when proven."""
        return "optimal" if self.proven_optimal else BEST_FOUND

    def routes_by_id(self, problem: Problem) -> dict[str, list[str]]:
        return {problem.robots[i].id: [problem.tasks[j].id for j in route]
                for i, route in self.routes.items() if route}


def reference(problem: Problem, objective: Objective | str, *, exact_limit: int = EXACT_LIMIT,
              time_limit: float = 30.0, solutions: int = 1000) -> Reference:
    """The exact optimum when the problem has at most `exact_limit` tasks, else the best routes
    OR-Tools finds within `solutions` accepted solutions (deterministic) and `time_limit`
    seconds (a safety cap)."""
    try:
        objective = Objective(objective)
    except ValueError:
        raise ConfigError(f"unknown objective {objective!r}; known: "
                          + ", ".join(o.value for o in Objective)) from None
    t0 = time.perf_counter()
    capped = False
    if len(problem.tasks) <= exact_limit:
        from .exact import solve_exact
        routes, method, proven = solve_exact(problem, objective).routes, EXACT, True
    else:
        from .routing import solve_routing
        found = solve_routing(problem, objective, solutions=solutions, time_limit=time_limit)
        routes, method, proven = found.routes, BEST_FOUND, False
        capped = found.capped
    seconds = time.perf_counter() - t0
    return Reference(evaluate(problem, routes).value(objective), routes, method, proven,
                     seconds, objective, capped)
