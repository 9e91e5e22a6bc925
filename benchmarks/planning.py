"""Reference values (mrta_zenoh.planning.reference): the exact recursion's solve time against
size, and the routing search's best found against the exact optimum where both exist.

    python benchmarks/planning.py [--quick]

One JSON line per figure. Instances are drawn from fixed seeds (3 robots, capabilities, half
the tasks arriving over 25 s, services up to 6 s): the same on every machine; the times are
this machine's. The baseline of the exact solve times is the smallest size in the same run."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from mrta_zenoh.planning.reference import reference  # noqa: E402
from tests.test_planning_reference import random_problem  # noqa: E402

OBJECTIVES = ("minsum", "makespan", "flowtime")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="fewer sizes and seeds")
    args = ap.parse_args()
    sizes = (4, 6, 8) if args.quick else (4, 6, 7, 8, 9, 10, 11)
    seeds = range(2) if args.quick else range(5)
    base: dict[str, float] = {}
    for n in sizes:
        for objective in OBJECTIVES:
            times = sorted(reference(random_problem(s, 3, n), objective, exact_limit=n).seconds
                           for s in seeds)
            median = times[len(times) // 2]
            base.setdefault(objective, median)
            print(json.dumps({"figure": "exact solve time", "robots": 3, "tasks": n,
                              "objective": objective, "median_s": round(median, 4),
                              "max_s": round(times[-1], 4),
                              "baseline_tasks": sizes[0],
                              "ratio_to_baseline": round(median / base[objective], 1)}),
                  flush=True)
    for n in sizes[1::2]:
        for objective in OBJECTIVES:
            gaps, secs = [], []
            for s in seeds:
                p = random_problem(s, 3, n)
                exact = reference(p, objective, exact_limit=n)
                found = reference(p, objective, exact_limit=0)
                gaps.append(found.value / exact.value - 1 if exact.value else 0.0)
                secs.append(found.seconds)
            print(json.dumps({"figure": "best found vs exact", "robots": 3, "tasks": n,
                              "objective": objective, "instances": len(gaps),
                              "equal": sum(g < 1e-9 for g in gaps),
                              "mean_gap_pct": round(100 * sum(gaps) / len(gaps), 3),
                              "max_gap_pct": round(100 * max(gaps), 3),
                              "routing_median_s": round(sorted(secs)[len(secs) // 2], 3)}),
                  flush=True)


if __name__ == "__main__":
    main()
