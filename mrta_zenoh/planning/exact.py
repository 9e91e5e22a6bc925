"""Exact reference values for small problems: dynamic programming over task subsets.

Why not a MILP. The routing MILP (arc variables per robot, big-M start times for waiting and
service, a max-variable for makespan) is the textbook weak formulation: its LP relaxation lets
the big-M time constraints go slack, so a solver closes the gap by branching. The subset
recursion below is exact by construction (every solve is proven optimal: no status or gap to
report), handles the three objectives with one piece of code, needs no solver, and is pure
Python. It grows as robots · 3ⁿ + robots · 2ⁿ · n² (`benchmarks/planning.py` measures it), so
`reference.py` uses it up to `exact_limit` tasks and the routing search (`routing.py`) past
that.

Robots do not interact in the model (no capacity, no shared resource), so an objective splits
robot by robot: total travel and flowtime are sums over robots, makespan a maximum. So

1. for each robot i and each set S of tasks it can serve, the best value f_i(S) of serving S
   alone, over every order (Held–Karp: states (S, last task));
2. the best split of all tasks into sets S_1, …, S_m, one per robot:
   g_k(U) = min over S ⊆ U of f_k(S) ⊕ g_{k−1}(U ∖ S), with ⊕ = + or max.

Step 1 per objective: total travel ignores times, so one label per state (the least travel);
makespan keeps the earliest completion (completion is non-decreasing in the time the previous
task ends, so the earliest dominates); flowtime keeps the Pareto set of (completion so far, sum
of completions) — a later but cheaper prefix may still win, so no single label suffices.

**Hard time windows** (docs/delivery.md, "Time windows"; `Problem.windows` hard and some task
with a due). Service starts at max(reach, arrival, earliest) and a task whose start would pass
its due cannot be added to the route (`_extend` gives no label). Then times matter to MinSum
too: a prefix that travels less but ends later may miss a due a faster one makes, so MinSum
keeps the Pareto set of (completion, travel) as flowtime does; makespan still keeps the
earliest completion (an earlier end never closes a window waiting cannot). Not every task can
always be served, so the reference is *hierarchical*: the most tasks served within their
windows, then the least objective among those (`solve_exact` takes the best split over every
set of tasks served, by (−tasks served, value)); a task nobody can reach by its due is missed.
Under soft windows a due binds nothing here (a late start is counted, not forbidden): the
earliest still delays service, and every task is served.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Iterator

from ..errors import ConfigError
from .problem import Problem, Windows
from .schedule import Objective


@dataclass(frozen=True)
class _Label:
    time: float                     # completion of the last task
    value: float                    # the objective's accumulated value
    task: int
    parent: "_Label | None"

    def route(self) -> list[int]:
        out, at = [], self
        while at is not None:
            out.append(at.task)
            at = at.parent
        return out[::-1]


def binding(problem: Problem) -> bool:
    """Whether a due can forbid a start: hard windows and some task with a due (module
    docstring); then the reference is hierarchical (most tasks served first)."""
    return problem.windows is Windows.HARD and any(math.isfinite(t.due) for t in problem.tasks)


def _extend(problem: Problem, i: int, label: _Label | None, j: int,
            objective: Objective, hard: bool = False) -> _Label | None:
    """The label of serving task j next after `label` (None: first); None when `hard` and
    its service would start after its due."""
    leg = problem.travel(i, None if label is None else label.task, j)
    task = problem.tasks[j]
    now = problem.robots[i].ready if label is None else label.time
    start = max(now + leg, task.opens)
    if hard and start > task.due:
        return None
    end = start + task.service
    before = 0.0 if label is None else label.value
    value = (before + leg if objective is Objective.MINSUM
             else end if objective is Objective.MAKESPAN else before + end)
    return _Label(end, value, j, label)


def _keep(labels: list[_Label], new: _Label | None, objective: Objective,
          hard: bool = False) -> list[_Label]:
    """The labels of one state once `new` is offered (see the module docstring)."""
    if new is None:
        return labels
    if objective is Objective.MINSUM and not hard:
        return [new] if not labels or new.value < labels[0].value else labels
    if objective is Objective.MAKESPAN:
        return [new] if not labels or new.time < labels[0].time else labels
    if any(o.time <= new.time and o.value <= new.value for o in labels):
        return labels
    return [o for o in labels if not (new.time <= o.time and new.value <= o.value)] + [new]


def _bits(mask: int) -> Iterator[int]:
    while mask:
        low = mask & -mask
        yield low.bit_length() - 1
        mask ^= low


def best_alone(problem: Problem, i: int, objective: Objective) -> dict[int, _Label]:
    """Robot i's best label for every non-empty set of tasks it can serve (bit mask → label)."""
    n = len(problem.tasks)
    able = sum(1 << j for j in range(n) if problem.capable(i, j))
    cap = problem.robots[i].capacity
    if cap == 0:
        return {}
    hard = binding(problem)
    states: dict[tuple[int, int], list[_Label]] = {}
    for j in _bits(able):
        first = _keep([], _extend(problem, i, None, j, objective, hard), objective, hard)
        if first:
            states[(1 << j, j)] = first
    # masks in increasing order: every state's predecessors are complete before it is extended
    for mask in range(1, 1 << n):
        if mask & ~able or (cap is not None and mask.bit_count() >= cap):
            continue  # not its to serve, or full: nothing more is added to it
        for last in _bits(mask):
            for label in states.get((mask, last), ()):
                for j in _bits(able & ~mask):
                    key = (mask | 1 << j, j)
                    kept = _keep(states.get(key, []), _extend(problem, i, label, j, objective,
                                                              hard), objective, hard)
                    if kept:
                        states[key] = kept
    best: dict[int, _Label] = {}
    for (mask, _), labels in states.items():
        for label in labels:
            if mask not in best or label.value < best[mask].value:
                best[mask] = label
    return best


@dataclass(frozen=True)
class Exact:
    value: float
    routes: dict[int, list[int]]


def solve_exact(problem: Problem, objective: Objective | str) -> Exact:
    """The optimum over every assignment of every task to a capable robot and every order.
    ConfigError when some task has no capable robot (no solution serves every task). Under
    binding hard windows: the most tasks served within their windows, then the least value
    (module docstring); a task no robot can serve is then missed, not an error."""
    objective = Objective(objective)
    n, m = len(problem.tasks), len(problem.robots)
    hard = binding(problem)
    for j in range(n if not hard else 0):
        if not any(problem.capable(i, j) for i in range(m)):
            raise ConfigError(f"task {problem.tasks[j].id}: no robot has capability "
                              f"{problem.tasks[j].capability!r}")
    combine = max if objective is Objective.MAKESPAN else (lambda a, b: a + b)
    full = (1 << n) - 1
    # g[U] = (value, {robot: route}) for the robots so far serving exactly U
    g: dict[int, tuple[float, dict[int, list[int]]]] = {0: (0.0, {})}
    for i in range(m):
        alone = best_alone(problem, i, objective)
        nxt: dict[int, tuple[float, dict[int, list[int]]]] = dict(g)  # robot i serves nothing
        for done, (value, routes) in g.items():
            rest = full & ~done
            sub = rest
            while sub:
                label = alone.get(sub)
                if label is not None:
                    total = combine(value, label.value)
                    key = done | sub
                    if key not in nxt or total < nxt[key][0]:
                        nxt[key] = (total, {**routes, i: label.route()})
                sub = (sub - 1) & rest
        g = nxt
    if hard:  # the most tasks served, then the least value; ties: the lower set of tasks
        full = min(g, key=lambda u: (-u.bit_count(), g[u][0], u))
    if full not in g:
        raise ConfigError("the robots' capacities (max tasks per robot) cannot serve every task")
    value, routes = g[full]
    return Exact(value if n else 0.0, {i: routes.get(i, []) for i in range(m)})

