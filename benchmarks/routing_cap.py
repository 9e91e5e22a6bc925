"""The routing search's cap against the machine's load: what one OR-Tools search with central's
budget (200 solutions, a 10 s cap) costs in CPU and in wall time, and whether a wall-clock cap
of that size would have stopped it (mrta_zenoh/planning/routing.py: the cap is CPU time since
issue 48).

    nice -n 19 python benchmarks/routing_cap.py [--sizes 20x20,50x50,100x50]

One JSON line per size: the search's CPU seconds (its thread's), its wall seconds on this
machine as loaded now, the load average, `capped` (the CPU cap) and `wall_cap_would_stop` (the
wall seconds past 98 % of the cap: what the former wall-clock cap decided). Instances: the
study's generator (delivery, seed 2) at the study's density (docs/study/README.md: 12 × 8 m up
to 20 robots, scaled by √(N / 20) above); N robots × M tasks all open, as central's first
search of an instance is. The baseline is the first size, in the same run."""

from __future__ import annotations

import argparse
import json
import math
import os
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from mrta_zenoh import instances  # noqa: E402
from mrta_zenoh.planning.routing import solve_routing  # noqa: E402

SOLUTIONS, CAP = 200, 10.0  # central's defaults (robot_agent/central/params.py)


def room(robots: int) -> list[float]:
    scale = math.sqrt(max(1.0, robots / 20))
    return [round(12 * scale, 1), round(8 * scale, 1)]


def measure(robots: int, tasks: int, folder: Path) -> dict:
    path = folder / f"r{robots}-t{tasks}.yaml"
    instances.generate("delivery", {"robots": robots, "tasks": tasks, "room": room(robots)}, 2,
                       path)
    loaded = instances.load(path, None)
    problem = loaded.kind.problem(loaded.doc)
    load = os.getloadavg()[0]
    c0, w0 = time.thread_time(), time.perf_counter()
    found = solve_routing(problem, "minsum", solutions=SOLUTIONS, time_limit=CAP)
    cpu, wall = time.thread_time() - c0, time.perf_counter() - w0
    return {"figure": f"routing search, {robots} robots x {tasks} tasks", "cpu_s": round(cpu, 2),
            "wall_s": round(wall, 2), "load": round(load, 1), "capped": found.capped,
            "wall_cap_would_stop": wall >= 0.98 * CAP}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", default="20x20,50x50,100x50",
                    help="ROBOTSxTASKS,… (the first is the baseline)")
    args = ap.parse_args()
    with tempfile.TemporaryDirectory(prefix="mrta-routing-cap-") as tmp:
        for size in args.sizes.split(","):
            robots, tasks = (int(x) for x in size.split("x"))
            print(json.dumps(measure(robots, tasks, Path(tmp))), flush=True)


if __name__ == "__main__":
    main()
