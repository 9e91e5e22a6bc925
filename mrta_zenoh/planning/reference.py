"""The reference value a run is compared with: one entry point over the exact recursion
(`exact.py`, small problems: proven optimal) and the routing search (`routing.py`, larger ones:
best found, never called optimal).

    reference(problem, "makespan")  →  Reference(value, routes, method, proven_optimal, seconds)

`routes` (robot index → task indices in service order) evaluate to `value` through
`schedule.evaluate`: the value is always the routes' own, computed in floats by the one
definition of the objectives.

Under hard time windows (a task with a due) the reference is hierarchical: the most tasks
served within their windows, then the least objective among routes serving that many
(exact.py, "Hard time windows"); `served` says how many, the tasks off every route are missed.
Past the exact limit, MinSum under binding windows is searched by PyVRP (pyvrp_routing.py),
every other case by OR-Tools (routing.py): on the same windowed MinSum instances PyVRP served as
many tasks as the best found in every case and OR-Tools served fewer in 6 of 8 at 40 tasks
(benchmarks/README.md, "Reference under time windows"); PyVRP has no makespan or flowtime
objective, so OR-Tools keeps those (and MinSum without windows, whose reference values runs
already hold).

An experiment runs one instance under many architectures and faults, and every run's analysis
asks for the same references (at 10 robots and 20 tasks, ~30 s of CPU per run: more than the
mission). With `$MRTA_REFERENCE_CACHE` (REFERENCE_CACHE_ENV) naming a folder, each reference is
solved once per problem and search budget and read back by every later run: the same value
and routes the solve gives (the solve is deterministic; only a search its time cap cut short
could differ, and that value is never reported). Runs solving the same problem at once take
turns (a lock per entry), so the second reads what the first wrote.
"""

from __future__ import annotations

import dataclasses
import fcntl
import json
import os
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable

from ..errors import ConfigError
from ..files import write_text
from ..sha import sha256
from .exact import binding
from .problem import Problem
from .schedule import Objective, evaluate

EXACT = "exact"
BEST_FOUND = "best found"
EXACT_LIMIT = 10      # tasks: the exact recursion up to here (3 robots × 10 tasks: < 1 s)
# the routing search's budget above it (accepted solutions): a run's reference and `mrta instance
# show`'s default alike, so one instance has one "best found" (issue 51: show searched 1,000,
# the run 200 — 44.885 against 46.392 on the README's instance). 1,000 took 20-30 s an objective
# there, reaching the time cap: machine-dependent, and added to every run's analysis
SOLUTIONS = 200
REFERENCE_CACHE_ENV = "MRTA_REFERENCE_CACHE"  # a folder of solved references (module docstring)


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
    def served(self) -> int:
        """Tasks on the routes (under hard windows the others are missed)."""
        return sum(len(r) for r in self.routes.values())

    @property
    def label(self) -> str:
        """What to call the value: "optimal" only when proven."""
        return "optimal" if self.proven_optimal else BEST_FOUND

    def routes_by_id(self, problem: Problem) -> dict[str, list[str]]:
        return {problem.robots[i].id: [problem.tasks[j].id for j in route]
                for i, route in self.routes.items() if route}


def reference(problem: Problem, objective: Objective | str, *, exact_limit: int = EXACT_LIMIT,
              time_limit: float = 30.0, solutions: int = SOLUTIONS) -> Reference:
    """The exact optimum when the problem has at most `exact_limit` tasks, else the best routes
    OR-Tools finds within `solutions` accepted solutions (PyVRP within 2 · `solutions`
    iterations for MinSum under binding windows: module docstring) — deterministic — and
    `time_limit` seconds (a safety cap)."""
    try:
        objective = Objective(objective)
    except ValueError:
        raise ConfigError(f"unknown objective {objective!r}; known: "
                          + ", ".join(o.value for o in Objective)) from None
    cache = os.environ.get(REFERENCE_CACHE_ENV)
    if cache:
        return _cached(Path(cache), problem, objective, exact_limit, time_limit, solutions)
    return _solve(problem, objective, exact_limit, time_limit, solutions)


def _solve(problem: Problem, objective: Objective, exact_limit: int, time_limit: float,
           solutions: int) -> Reference:
    t0 = time.perf_counter()
    capped = False
    if len(problem.tasks) <= exact_limit:
        from .exact import solve_exact
        routes, method, proven = solve_exact(problem, objective).routes, EXACT, True
    elif objective is Objective.MINSUM and binding(problem):
        from .pyvrp_routing import solve_pyvrp
        found = solve_pyvrp(problem, objective, iterations=2 * solutions,
                            time_limit=time_limit)
        routes, method, proven, capped = found.routes, BEST_FOUND, False, found.capped
    else:
        from .routing import solve_routing
        found = solve_routing(problem, objective, solutions=solutions, time_limit=time_limit)
        routes, method, proven = found.routes, BEST_FOUND, False
        capped = found.capped
    seconds = time.perf_counter() - t0
    return Reference(evaluate(problem, routes).value(objective), routes, method, proven,
                     seconds, objective, capped)


def _plain(x: Any) -> Any:
    """`x` as JSON data that is the same in every process: every field of a dataclass, a set
    sorted (a frozenset's repr follows the process's string hashing, so two runs of one
    instance would miss each other's entries)."""
    if dataclasses.is_dataclass(x):
        return {f.name: _plain(getattr(x, f.name)) for f in dataclasses.fields(x)}
    if isinstance(x, (set, frozenset)):
        return sorted(_plain(v) for v in x)
    if isinstance(x, (list, tuple)):
        return [_plain(v) for v in x]
    if isinstance(x, dict):
        return {str(k): _plain(v) for k, v in x.items()}
    return x


def _cached(folder: Path, problem: Problem, objective: Objective, exact_limit: int,
            time_limit: float, solutions: int) -> Reference:
    """The reference from `folder`, solved and written there first if it is not yet: keyed by
    everything the solve reads (the problem with its distances, the objective, the budget)."""
    text = json.dumps([_plain(problem), objective.value, exact_limit, time_limit, solutions],
                      sort_keys=True)

    def solve() -> dict:
        ref = _solve(problem, objective, exact_limit, time_limit, solutions)
        return {"value": ref.value, "routes": ref.routes, "method": ref.method,
                "proven_optimal": ref.proven_optimal, "seconds": ref.seconds,
                "capped": ref.capped}

    d = cache_entry(folder, sha256(text.encode()).hexdigest()[:32], solve)
    return Reference(d["value"], {int(i): r for i, r in d["routes"].items()}, d["method"],
                     d["proven_optimal"], d["seconds"], objective, d["capped"])


def cache_entry(folder: Path, key: str, solve: Callable[[], dict]) -> dict:
    """The JSON entry `key` of the cache `folder`, made by `solve` and written there first if it
    is not yet; runs asking for one entry at once take turns (a lock per entry), so the second
    reads what the first wrote. Every run — the first included — gets the entry as read back
    (what JSON makes of `solve`'s value: int keys become strings)."""
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / f"{key}.json"
    with open(folder / f".{key}.lock", "a") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)  # released when the file closes, however this ends
        if not path.is_file():
            write_text(path, json.dumps(solve()))
        return json.loads(path.read_text())
