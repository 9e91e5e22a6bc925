"""central's decision time against the number of tasks N: what one dispatcher decision costs
(planner.solve: the residual problem, the solve, the comparison with the current plan), at
the start (every task open, no plan yet) and at a completion (each robot committed to its
first planned task, the current plan compared with a fresh solve).

    python benchmarks/central.py [--quick]

One JSON line per figure. Instances are drawn from fixed seeds (tests/test_planning_reference:
3 robots up to 12 tasks, N/4 robots above, capabilities, a third of the tasks arriving over
25 s, known here from the start): the same on every machine; the times are this machine's.
The baseline is the smallest N in the same run. Up to the dispatcher's `exact_limit` (8) the
decision is exact; above, OR-Tools with its deterministic budget (`solutions`, 200)."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from mrta_agent.central.params import DispatcherParams  # noqa: E402
from mrta_agent.central.planner import Situation, solve  # noqa: E402
from tests.test_planning_reference import random_problem  # noqa: E402


def decide(problem, params: DispatcherParams, commitments, current):
    robots = tuple(r.id for r in problem.robots)
    committed = {c[-1] for c in commitments.values() if c}
    situation = Situation({r: commitments.get(r, ()) for r in robots}, robots,
                          tuple(t.id for t in problem.tasks if t.id not in committed))
    return solve(problem, situation, params.objective, exact_limit=params.exact_limit,
                 solutions=params.solutions, time_limit=params.time_limit,
                 search_limit=params.search_limit, current=current)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="fewer sizes and seeds")
    args = ap.parse_args()
    sizes = (4, 8, 12) if args.quick else (4, 6, 8, 10, 12, 16, 24)
    seeds = range(2) if args.quick else range(3)
    params = DispatcherParams()
    decide(random_problem(0, 2, 3), params, {}, None)  # the solvers' imports, not a decision
    base: dict[str, float] = {}
    for n in sizes:
        robots = 3 if n <= 12 else n // 4
        starts, completions, methods = [], [], {"start": set(), "completion": set()}
        for s in seeds:
            p = random_problem(s, robots, n)
            first = decide(p, params, {}, None)
            starts.append(first.seconds)
            # a completion: each robot set off to its first planned task (its commitment)
            commitments = {r: tuple(route[:1]) for r, route in first.routes.items()}
            rest = {r: route[1:] for r, route in first.routes.items()}
            again = decide(p, params, commitments, rest)
            completions.append(again.seconds)
            methods["start"].add(first.method)
            methods["completion"].add(again.method)  # "kept": the fresh solve did not beat it
        for label, times in (("start", starts), ("completion", completions)):
            times = sorted(times)
            median = times[len(times) // 2]
            base.setdefault(label, median)
            print(json.dumps({"figure": "central decision time", "decision": label,
                              "robots": robots, "tasks": n,
                              "methods": sorted(methods[label]),
                              "objective": params.objective.value,
                              "median_ms": round(1000 * median, 2),
                              "max_ms": round(1000 * times[-1], 2),
                              "instances": len(times), "baseline_tasks": sizes[0],
                              "ratio_to_baseline": round(median / base[label], 1)}),
                  flush=True)


if __name__ == "__main__":
    main()
