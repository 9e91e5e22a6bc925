"""The reference under hard time windows (mrta_zenoh.planning.exact, "Hard time windows"):
OR-Tools' routing search (routing.py) against PyVRP (pyvrp_routing.py) on the same windowed
MinSum instances — against the exact optimum where it exists (≤ 10 tasks), against each other
above.

    python benchmarks/windows_reference.py [--quick]

One JSON line per figure. The key is hierarchical: tasks served within their windows first (a
solver that serves fewer loses, whatever its travel), then MinSum. Instances are drawn from
fixed seeds (tests/test_planning_windows_reference.py `windowed_problem`: capabilities,
windows of 2–14 s divided by the tightness, opening in the first 20 s); the same on every
machine, the times are this machine's. Budgets: OR-Tools the reference's default (1,000
accepted solutions), PyVRP 2,000 iterations — each a count, so deterministic; the baseline of a
time is OR-Tools' on the same instances in the same run."""

from __future__ import annotations

import argparse
import json
import statistics
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from mrta_zenoh.planning import evaluate  # noqa: E402
from mrta_zenoh.planning.pyvrp_routing import solve_pyvrp  # noqa: E402
from mrta_zenoh.planning.reference import reference  # noqa: E402
from mrta_zenoh.planning.routing import solve_routing  # noqa: E402
from tests.test_planning_windows_reference import windowed_problem  # noqa: E402


def solve(name: str, p, budget: int):
    t0 = time.perf_counter()
    found = (solve_routing(p, "minsum", solutions=budget) if name == "ortools"
             else solve_pyvrp(p, iterations=budget))
    seconds = time.perf_counter() - t0
    ev = evaluate(p, found.routes)
    return ev.served, ev.total_travel, seconds, found.capped


def key_gap(served: int, value: float, best_served: int, best_value: float) -> float | None:
    """The MinSum gap (%) when as many tasks are served as the best; None when fewer."""
    if served < best_served:
        return None
    return 100.0 * (value / best_value - 1) if best_value else 0.0


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="fewer sizes and seeds")
    args = ap.parse_args()
    seeds = range(3) if args.quick else range(8)
    budgets = {"ortools": 1000, "pyvrp": 2000}
    for tasks, robots in ((10, 3),) + (((20, 3),) if args.quick else ((20, 3), (40, 5))):
        for tight in (1.0, 3.0):
            rows = {name: [] for name in budgets}
            exact = []
            for s in seeds:
                p = windowed_problem(1000 + s, robots, tasks, tight=tight)
                results = {name: solve(name, p, b) for name, b in budgets.items()}
                if tasks <= 10:
                    ref = reference(p, "minsum")
                    best = (ref.served, ref.value)
                    exact.append(ref.seconds)
                else:
                    best = max(((r[0], -r[1]) for r in results.values()))
                    best = (best[0], -best[1])
                for name, (served, value, seconds, capped) in results.items():
                    rows[name].append((served, value, seconds, capped,
                                       key_gap(served, value, *best), best[0] - served))
            for name, r in rows.items():
                gaps = [g for *_, g, _ in r if g is not None]
                secs = [x[2] for x in r]
                base = [x[2] for x in rows["ortools"]]
                print(json.dumps({
                    "figure": "windowed reference: " + ("vs exact" if tasks <= 10 else
                                                        "vs the better of the two"),
                    "solver": name, "budget": budgets[name], "robots": robots, "tasks": tasks,
                    "tightness": tight, "instances": len(r),
                    "fewer_served": sum(x[5] > 0 for x in r),
                    "equal": sum(g < 1e-6 for g in gaps),
                    "mean_gap_pct": round(statistics.fmean(gaps), 3) if gaps else None,
                    "max_gap_pct": round(max(gaps), 3) if gaps else None,
                    "median_s": round(statistics.median(secs), 3),
                    "baseline": "ortools median_s",
                    "ratio_to_baseline": round(statistics.median(secs)
                                               / statistics.median(base), 2),
                    "capped": sum(x[3] for x in r),
                    **({"exact_median_s": round(statistics.median(exact), 3)} if exact else {}),
                }), flush=True)


if __name__ == "__main__":
    main()
