"""Experiment backends: runs per minute on a Dask cluster of two local workers against
`mrta experiment --jobs 2`, the same matrix in the same run.

Prints one JSON line per figure:
  experiment_cluster_start  wall seconds for a scheduler and two workers (`--nthreads 1
                            --resources runs=1`, loopback) to be up: paid once per cluster
  experiment_backend        one sweep of the matrix (patrol, 60 s, seeds × [none, robot2@30]):
                            wall seconds and runs per minute, backend "local" (--jobs 2) or
                            "dask" (--scheduler, two workers); with --repeat, alternately
  experiment_dask_vs_local  the ratio of the means, and whether both gave the same rows (the
                            columns lockstep makes identical)

Run: python benchmarks/experiment_dask.py [--seeds 6] [--repeat 1]   (needs mrta-zenoh[dask])
"""

from __future__ import annotations

import argparse
import csv
import json
import os
import signal
import socket
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

HERE = os.path.abspath(__file__)
sys.path[:] = [p for p in sys.path if os.path.abspath(p or ".") != os.path.dirname(HERE)]

from mrta_zenoh.processes import ProcessGroup, mrta_argv  # noqa: E402

SAME = ("run", "seed", "failure", "status", "takeover_seconds", "taken_over_by",
        "first_full_allocation")


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def start_cluster(folder: Path, workers: int = 2) -> tuple[str, list[subprocess.Popen]]:
    """A scheduler and `workers` workers on 127.0.0.1, as the README starts them."""
    import distributed

    address = f"tcp://127.0.0.1:{free_port()}"
    procs = []

    def start(name: str, *args: str) -> None:
        with (folder / f"{name}.log").open("w") as log:
            procs.append(subprocess.Popen([sys.executable, "-m", *args], stdout=log,
                                          stderr=subprocess.STDOUT, stdin=subprocess.DEVNULL,
                                          cwd=folder))

    start("scheduler", "distributed.cli.dask_scheduler", "--host", "127.0.0.1", "--port",
          address.rsplit(":", 1)[1], "--no-dashboard")
    for i in range(workers):
        start(f"worker{i}", "distributed.cli.dask_worker", address, "--host", "127.0.0.1",
              "--nthreads", "1", "--resources", "runs=1", "--no-dashboard", "--name",
              f"worker{i}", "--local-directory", str(folder / f"worker{i}"))
    with distributed.Client(address, timeout=60, set_as_default=False) as client:
        client.wait_for_workers(workers, timeout=60)
    return address, procs


def stop_cluster(procs: list[subprocess.Popen]) -> None:
    for proc in reversed(procs):  # workers first, the scheduler last; by PID
        if proc.poll() is None:
            proc.send_signal(signal.SIGTERM)
            try:
                proc.wait(20)
            except subprocess.TimeoutExpired:
                proc.kill()
                proc.wait(5)


def sweep(matrix: Path, out: Path, *backend: str) -> tuple[float, list[dict]]:
    t0 = time.monotonic()
    with ProcessGroup() as group:
        run = group.start(mrta_argv("-q", "experiment", matrix, "--output", out, *backend),
                          name="experiment", merge_stderr=True)
        rc = run.wait(3600)
    wall = time.monotonic() - t0
    if rc not in (0, 1):
        raise SystemExit(f"experiment {' '.join(backend)} exited {rc}: {run.tail(20)}")
    return wall, list(csv.DictReader((out / "results.csv").open()))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=6, help="seeds per failure (2 failures)")
    ap.add_argument("--repeat", type=int, default=1, help="sweeps per backend, alternately")
    args = ap.parse_args()
    runs = 2 * args.seeds
    with tempfile.TemporaryDirectory(prefix="mrta-bench-dask-") as tmp:
        tmp = Path(tmp)
        matrix = tmp / "exp.yaml"
        matrix.write_text(f"application: patrol\nduration: 60\n"
                          f"seeds: {list(range(1, args.seeds + 1))}\n"
                          "failures: [none, robot2@30]\n")
        t0 = time.monotonic()
        address, procs = start_cluster(tmp)
        try:
            print(json.dumps({"figure": "experiment_cluster_start", "workers": 2,
                              "wall_s": round(time.monotonic() - t0, 1)}), flush=True)
            walls: dict[str, list[float]] = {"local": [], "dask": []}
            rows: dict[str, list[dict]] = {}
            for i in range(args.repeat):
                for backend, flags in (("local", ("--jobs", "2")),
                                       ("dask", ("--scheduler", address))):
                    wall, rows[backend] = sweep(matrix, tmp / f"{backend}{i}", *flags)
                    walls[backend].append(wall)
                    print(json.dumps({"figure": "experiment_backend", "backend": backend,
                                      "runs": runs, "duration_s": 60, "wall_s": round(wall, 1),
                                      "runs_per_minute": round(60 * runs / wall, 2),
                                      "load_1min": os.getloadavg()[0]}), flush=True)
        finally:
            stop_cluster(procs)
    same = [{k: r.get(k) for k in SAME} for r in rows["local"]] == \
        [{k: r.get(k) for k in SAME} for r in rows["dask"]]
    local, dask = statistics.fmean(walls["local"]), statistics.fmean(walls["dask"])
    print(json.dumps({"figure": "experiment_dask_vs_local", "runs": runs,
                      "local_runs_per_minute": round(60 * runs / local, 2),
                      "dask_runs_per_minute": round(60 * runs / dask, 2),
                      "ratio": round(local / dask, 2), "same_rows": same}), flush=True)


if __name__ == "__main__":
    main()
