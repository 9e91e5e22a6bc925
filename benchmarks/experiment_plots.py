"""What a run's pictures cost, and what `mrta experiment` saves by drawing them once per cell.

Prints one JSON line per figure:
  demo_pictures        one patrol run (`mrta demo --speed 0`) with its pictures and without
                       (`--no-plots`), alternately, the same seed: wall seconds and CPU seconds
                       of the run and every process it started (children's rusage)
  demo_pictures_cost   the means' difference: what the pictures add to one run
  experiment_pictures  one `mrta experiment --jobs 2` of 2 cells × SEEDS seeds: pictures for
                       the first run of each cell (the default) against `--no-plots`; beside
                       them, the estimate for every run drawing its own (the default plus the
                       per-run cost for each run that did not), the behaviour before

Run: python benchmarks/experiment_plots.py [--seeds 3] [--duration 30] [--repeat 2]
"""

from __future__ import annotations

import argparse
import csv
import json
import os
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

HERE = os.path.abspath(__file__)
sys.path[:] = [p for p in sys.path if os.path.abspath(p or ".") != os.path.dirname(HERE)]

from mrta_zenoh.processes import mrta_argv  # noqa: E402


def timed(argv: list[str], ok: tuple[int, ...] = (0,)) -> tuple[float, float]:
    """Wall and CPU seconds (this child and everything under it) of one command."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.monotonic()
    done = subprocess.run(argv, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    wall = time.monotonic() - t0
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if done.returncode not in ok:
        raise SystemExit(f"{' '.join(argv)} exited {done.returncode}:\n{done.stderr[-2000:]}")
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    return wall, cpu


def demo(folder: Path, duration: float, plots: bool) -> tuple[float, float]:
    return timed(mrta_argv("-q", "demo", "--duration", str(duration), "--speed", "0",
                           "--seed", "1", "--fail", "none", "--no-live", "--output",
                           str(folder), *([] if plots else ["--no-plots"])))


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seeds", type=int, default=3)
    ap.add_argument("--duration", type=float, default=30.0)
    ap.add_argument("--repeat", type=int, default=2)
    args = ap.parse_args()
    with tempfile.TemporaryDirectory(prefix="mrta-plots-bench-") as tmp:
        root = Path(tmp)
        runs: dict[bool, list[tuple[float, float]]] = {True: [], False: []}
        for i in range(args.repeat):
            for plots in (True, False):
                wall, cpu = demo(root / f"demo{i}{plots}", args.duration, plots)
                runs[plots].append((wall, cpu))
                print(json.dumps({"figure": "demo_pictures", "plots": plots,
                                  "duration_s": args.duration, "wall_s": round(wall, 2),
                                  "cpu_s": round(cpu, 2)}), flush=True)
        mean = {p: (statistics.fmean(w for w, _ in v), statistics.fmean(c for _, c in v))
                for p, v in runs.items()}
        cost_wall, cost_cpu = (mean[True][0] - mean[False][0], mean[True][1] - mean[False][1])
        print(json.dumps({"figure": "demo_pictures_cost", "wall_s": round(cost_wall, 2),
                          "cpu_s": round(cost_cpu, 2),
                          "share_of_cpu": round(cost_cpu / mean[True][1], 3)}), flush=True)
        exp = root / "exp.yaml"
        seeds = ", ".join(str(s) for s in range(1, args.seeds + 1))
        exp.write_text(f"application: patrol\nduration: {args.duration:g}\nseeds: [{seeds}]\n"
                       "failures: [none, robot2@10]\n")
        n = 2 * args.seeds
        measured = {}
        for mode, extra in (("first_run_per_cell", []), ("none", ["--no-plots"])):
            # exit 1: a run failed (a loaded machine's start-up timeout): timed all the same,
            # and its error said
            wall, cpu = timed(mrta_argv("-q", "experiment", str(exp), "--output",
                                        str(root / mode), "--jobs", "2", *extra), ok=(0, 1))
            measured[mode] = (wall, cpu)
            with (root / mode / "results.csv").open(newline="") as f:
                failed = [r["error"] for r in csv.DictReader(f) if r["status"] != "ok"]
            print(json.dumps({"figure": "experiment_pictures", "pictures": mode, "runs": n,
                              "wall_s": round(wall, 2), "cpu_s": round(cpu, 2),
                              "failed_runs": failed}), flush=True)
        wall, cpu = measured["first_run_per_cell"]
        print(json.dumps({"figure": "experiment_pictures", "pictures": "every_run (estimate)",
                          "runs": n, "cpu_s": round(cpu + (n - 2) * cost_cpu, 2),
                          "wall_s_jobs2": round(wall + (n - 2) * cost_wall / 2, 2)}), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
