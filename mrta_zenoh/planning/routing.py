"""Best-found reference values for problems too large for the exact recursion: OR-Tools routing.

Why OR-Tools (not PyVRP). Every part of the model maps onto one of its documented features:
per-robot speeds are per-vehicle transit matrices (`AddDimensionWithVehicleTransits`,
`SetArcCostEvaluatorOfVehicle`), capabilities are the vehicles allowed at a node
(the node's vehicle variable), arrivals are time windows with waiting as slack, makespan is the
time dimension's global span cost, flowtime the sum of cumul costs (a soft upper bound of 0 at
each task: cost = the time service starts), both weighted over the travel cost, which only
breaks ties. PyVRP solves VRPTW with a genetic
search and a fixed objective (distance, duration, fixed costs): neither makespan nor flowtime
is among its objectives, and per-vehicle speeds need a profile per robot.

Time windows: a task's time cumul (when its service starts) lies in [max(arrival, earliest),
due]; under binding hard windows (`exact.binding`) each task is a disjunction whose drop costs
`DROP` — more than any set of routes' whole cost — so the search serves the most tasks it
can before it lowers the objective (the hierarchical reference, exact.py). OR-Tools times are
rounded to the ms, so routes are checked again in floats (`_keep_in_windows`): a task whose
start the rounding let pass its due is left off its route.

Open routes (no return to the start, as the objectives define): every robot ends at one dummy
node reached from anywhere at no cost. OR-Tools works on integers: times are in milliseconds
(`SCALE`); the value reported is recomputed from the routes in floats by `schedule.evaluate`,
so it is the routes' own value whatever the rounding.

Deterministic. The search (parallel cheapest insertion — on makespan and flowtime it started
from far better routes than cheapest-arc, which follows travel alone — then guided local
search) stops after `solutions` accepted solutions — a count, not a time, so the same problem
gives the same routes on any machine; `time_limit` is a safety cap, and a search stopped by it
says so (`capped`), because then the result depends on the machine's speed. No sub-search has a
wall limit of its own below that cap (`search_parameters`). A best-found value is never called optimal.

**The cap is CPU time, not wall time** (issue 48). It counts the CPU seconds of the searching
thread, looked at each time the search accepts a solution (`AddAtSolutionCallback`: a few
hundred Python calls a search; a `CustomLimit`, called at every search node, cost 60 % more
CPU at 20 / 20). A wall-clock cap made the study's 50-robot runs inexact on a loaded machine:
central's search of 50 open tasks among 50 robots needs ≈ 2.7 CPU-s, which took 18.5 s of
wall time at nice 19 beside other work — past a 10 s wall cap, so the search stopped on the
load, not on its budget (benchmarks/README.md, "The routing search's cap"). CPU time grows with
the work, not with the neighbours. A search that finds no next solution (every task
unservable in its window: one solution, dropping them all) is never looked at by a
per-solution check, so it is bounded by a count too: BRANCHES_PER_SOLUTION branches of the
search per solution of its budget — ≈ 6 a solution in a search that finds them (20 / 20 and
50 / 50 alike), thousands a CPU-second in one that finds none — deterministic, so a search
it stops is not capped. OR-Tools' own limit (wall time) stays as a last resort at WALL_FACTOR
times the cap; a search it stops is capped.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass

from ..errors import ConfigError
from .exact import binding
from .problem import Problem
from .schedule import Objective, route_visits

SCALE = 1000.0          # OR-Tools integer units per second
WEIGHT = 100            # makespan's span / flowtime's cumul cost per ms, over the travel tie-break (1)
DROP = 10 ** 13         # a dropped task's cost under hard windows (module docstring)
WALL_FACTOR = 20        # OR-Tools' wall-clock limit: this many times the CPU cap (last resort)
BRANCHES_PER_SOLUTION = 500  # the search's branch budget per solution of its budget (docstring)


@dataclass(frozen=True)
class BestFound:
    routes: dict[int, list[int]]
    capped: bool        # stopped by the time limit (then not reproducible across machines)


class SearchTimeout(ConfigError):
    """The search's time limit ended it before it found any route (a 1 ms `time_limit`): no
    answer at all, where a search stopped by it after a first solution is `capped`. A caller
    that must decide anyway (central's dispatcher) falls back on a construction of its own and
    reports the decision capped; any other caller gets this one line (exit 2)."""


def solve_routing(problem: Problem, objective: Objective | str, *, solutions: int = 2000,
                  time_limit: float = 30.0) -> BestFound:
    """The best routes OR-Tools finds serving every task (ConfigError: a task nobody can
    serve). `solutions`: the search's deterministic budget; `time_limit`: its safety cap (CPU s
    of the search, module docstring)."""
    from ortools.constraint_solver import pywrapcp, routing_enums_pb2

    objective = Objective(objective)
    m, n = len(problem.robots), len(problem.tasks)
    if m == 0 or n == 0:
        return BestFound({i: [] for i in range(m)}, False)
    hard = binding(problem)
    for j in range(n if not hard else 0):
        if not any(problem.capable(i, j) for i in range(m)):
            raise ConfigError(f"task {problem.tasks[j].id}: no robot has capability "
                              f"{problem.tasks[j].capability!r}")
    end = m + n  # nodes: robots' starts, tasks, the dummy end
    manager = pywrapcp.RoutingIndexManager(end + 1, m, list(range(m)), [end] * m)
    routing = pywrapcp.RoutingModel(manager)

    def task_of(node: int) -> int | None:
        return node - m if m <= node < end else None

    def travel_ms(i: int, a: int, b: int) -> int:
        """Robot i's travel from node a to node b (ms); nothing into the dummy end, and never
        into another robot's start (a start is only ever left)."""
        if b == end or b < m or a == end:
            return 0
        src = task_of(a) if a >= m else None
        if src is None and a != i:
            return 0  # another robot's start: not on robot i's route
        return round(problem.travel(i, src, b - m) * SCALE)

    def service_ms(a: int) -> int:
        j = task_of(a)
        return 0 if j is None else round(problem.tasks[j].service * SCALE)

    nodes = range(end + 1)
    travel = [[[travel_ms(i, a, b) for b in nodes] for a in nodes] for i in range(m)]
    travel_cb = [routing.RegisterTransitMatrix(t) for t in travel]
    time_cb = [routing.RegisterTransitMatrix([[t[a][b] + service_ms(a) for b in nodes]
                                              for a in nodes]) for t in travel]
    for i in range(m):
        routing.SetArcCostEvaluatorOfVehicle(travel_cb[i], i)
    ready = [round(r.ready * SCALE) for r in problem.robots]
    horizon = (sum(max(map(max, t)) for t in travel) + sum(service_ms(a) for a in nodes)
               + round(max(t.opens for t in problem.tasks) * SCALE) + max(ready)) * 2 + 1
    routing.AddDimensionWithVehicleTransits(time_cb, horizon, horizon, False, "time")
    clock = routing.GetDimensionOrDie("time")
    for i in range(m):  # a robot leaves its start at its ready time (0 for a fresh one)
        clock.CumulVar(routing.Start(i)).SetValue(ready[i])
    if any(r.capacity is not None for r in problem.robots):
        count = routing.RegisterUnaryTransitCallback(
            lambda index: 1 if task_of(manager.IndexToNode(index)) is not None else 0)
        routing.AddDimensionWithVehicleCapacity(
            count, 0, [n if r.capacity is None else r.capacity for r in problem.robots], True,
            "tasks")
    for j, task in enumerate(problem.tasks):
        index = manager.NodeToIndex(m + j)
        clock.CumulVar(index).SetMin(round(task.opens * SCALE))
        if hard:
            clock.CumulVar(index).SetMax(min(horizon, round(task.due * SCALE))
                                         if math.isfinite(task.due) else horizon)
            routing.AddDisjunction([index], DROP)
        # the vehicles allowed at a node (SetAllowedVehiclesForIndex's effect; its Python
        # binding refuses a list in this release)
        routing.VehicleVar(index).RemoveValues([i for i in range(m) if not problem.capable(i, j)])
        if objective is Objective.FLOWTIME:
            clock.SetCumulVarSoftUpperBound(index, 0, WEIGHT)
    if objective is Objective.MAKESPAN:
        clock.SetGlobalSpanCostCoefficient(WEIGHT)

    wall = time_limit * WALL_FACTOR
    params = search_parameters(solutions, wall)
    spent = _CpuCap(routing, time_limit)
    routing.AddAtSolutionCallback(spent.check)
    never = 2 ** 62  # no limit on this count: the solver's own "none"
    routing.AddSearchMonitor(routing.solver().Limit(
        never, BRANCHES_PER_SOLUTION * solutions, never, never, True, True))
    t0 = time.perf_counter()
    solution = routing.SolveWithParameters(params)
    cut = spent.hit or time.perf_counter() - t0 >= 0.98 * wall
    if solution is None:
        if cut or routing.status() == routing_enums_pb2.RoutingSearchStatus.ROUTING_FAIL_TIMEOUT:
            raise SearchTimeout(f"OR-Tools found no route at all within its time limit of "
                                f"{time_limit:g} s ({n} tasks, {m} robots): raise time_limit")
        raise ConfigError(f"OR-Tools found no route serving every task "
                          f"(status {routing.status()})")
    routes: dict[int, list[int]] = {}
    for i in range(m):
        index, route = routing.Start(i), []
        while not routing.IsEnd(index):
            j = task_of(manager.IndexToNode(index))
            if j is not None:
                route.append(j)
            index = solution.Value(routing.NextVar(index))
        routes[i] = route
    if hard:
        routes = _keep_in_windows(problem, routes)
    return BestFound(routes, cut)


class _CpuCap:
    """Ends a search whose thread has spent `seconds` of CPU time, looked at each solution
    (module docstring): OR-Tools has no CPU limit, so the solver is told to finish
    (`FinishCurrentSearch`: the best solution so far is the answer; its `UpdateTimeLimit`
    takes an absl::Duration the Python binding cannot make). The search runs on the calling
    thread, so `time.thread_time` is its CPU time (and no other thread's)."""

    def __init__(self, routing, seconds: float):
        self.routing, self.seconds, self.hit = routing, seconds, False
        self.start = time.thread_time()

    def check(self) -> None:
        if not self.hit and time.thread_time() - self.start >= self.seconds:
            self.hit = True
            self.routing.solver().FinishCurrentSearch()


def search_parameters(solutions: int, time_limit: float):
    """The search's parameters: parallel cheapest insertion, then guided local search, ended by
    `solutions` accepted solutions; `time_limit` (s) caps the whole search and each of its
    large-neighbourhood sub-searches alike.

    Why the sub-searches too. OR-Tools cuts each sub-search of its large-neighbourhood
    operators (the cheapest-insertion path LNS, on by default) at `lns_time_limit`, 100 ms of
    wall time by default: on a slower or busier machine a cut comes earlier, another neighbour
    is taken and the search goes another way. Measured (2026-12-08, 5 robots, flowtime): on 60
    tasks a 1 µs limit — a machine that much slower — gave 1,697.7 where 1 ms, 10 ms and 100 ms
    gave 1,114.6; on 205 tasks at load 20, 20 ms, 100 ms and 30 s gave the same routes (6.5
    CPU-s). With the sub-searches bounded by the whole cap only, the solution count alone ends
    the search, and a search that does reach the cap still says so (`capped`). Those two are
    the only wall limits among the parameters (tests/test_planning_reference.py walks them)."""
    from ortools.constraint_solver import pywrapcp, routing_enums_pb2

    params = pywrapcp.DefaultRoutingSearchParameters()
    params.first_solution_strategy = (
        routing_enums_pb2.FirstSolutionStrategy.PARALLEL_CHEAPEST_INSERTION)
    params.local_search_metaheuristic = (
        routing_enums_pb2.LocalSearchMetaheuristic.GUIDED_LOCAL_SEARCH)
    params.solution_limit = solutions
    params.time_limit.FromMicroseconds(max(1, round(time_limit * 1e6)))  # 0 would be no limit
    params.lns_time_limit.CopyFrom(params.time_limit)
    return params


def _keep_in_windows(problem: Problem, routes: dict[int, list[int]]) -> dict[int, list[int]]:
    """`routes` with every task whose start, timed in floats, passes its due left off (one at
    a time, the first such on a route, until none does: leaving one off only moves later
    starts earlier when travel keeps the triangle inequality, and checking again costs
    nothing when it does not)."""
    out = {}
    for i, route in routes.items():
        route = list(route)
        while True:
            late = [v.task for v in route_visits(problem, i, route)
                    if v.start > problem.tasks[v.task].due]
            if not late:
                break
            route.remove(late[0])
        out[i] = route
    return out
