"""Tasks at run time, submit to served: how long a burst of submitted tasks waits to be served
under each architecture that takes them, against the burst's size.

Each run is `mrta demo` of the default delivery mission whose instance carries the burst as a
summary's `submitted` section does — N tasks entering at 0.1 s (a grid of the room, priorities
0–2) — so the run's intake releases them through the same path a live burst takes, and the run
is exact in lockstep (the same figures on any machine, but for the wall time). Per run: how
many of the N were served by the end, the simulated time from entering to served (median, 95th
percentile, max), and the run's wall time. The baseline, in the same run: the instance's own
tasks' time from arrival to served. Prints one JSON line per figure.

Run: python benchmarks/task_served.py [--bursts 10,200] [--architectures central,ssi,tessi,cbba]
     [--duration 60]
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

HERE = os.path.abspath(__file__)
sys.path[:] = [p for p in sys.path if os.path.abspath(p or ".") != os.path.dirname(HERE)]

import yaml  # noqa: E402

from mrta_zenoh.architectures import architectures  # noqa: E402

ROOT = Path(HERE).parents[1]
INSTANCE = ROOT / "configs" / "applications" / "delivery" / "config" / "instance.yaml"
SPOTS = [(x, y + 0.5) for x in range(-3, 5) for y in range(-3, 4)]
ENTER = 0.1  # s: when the burst enters


def instance_with_burst(n: int) -> dict:
    doc = yaml.safe_load(INSTANCE.read_text())
    doc["submitted"] = [{"at": ENTER, "op": "submit", "id": f"s{i}", "priority": i % 3,
                         "submitter": "bench",
                         "task": {"position": [float(SPOTS[i % len(SPOTS)][0]),
                                               SPOTS[i % len(SPOTS)][1]], "service": 1.0}}
                        for i in range(n)]
    return doc


def spread(values: list[float]) -> dict:
    if not values:
        return {"median_s": None, "p95_s": None, "max_s": None}
    values = sorted(values)
    return {"median_s": round(statistics.median(values), 2),
            "p95_s": round(values[min(len(values) - 1, int(0.95 * len(values)))], 2),
            "max_s": round(values[-1], 2)}


def run(arch: str, n: int, duration: float, folder: Path) -> list[dict]:
    path = folder / f"{arch}-{n}.yaml"
    path.write_text(yaml.safe_dump(instance_with_burst(n)))
    out = folder / f"{arch}-{n}"
    t0 = time.perf_counter()
    subprocess.run([sys.executable, "-m", "mrta_zenoh.cli.main", "demo", "--application",
                    "delivery", "--architecture", arch, "--instance", str(path), "--duration",
                    str(duration), "--speed", "0", "--fail", "none", "--no-live", "--no-plots",
                    "--output", str(out)], check=True, capture_output=True,
                   env=dict(os.environ, RUST_LOG="error"))
    wall = time.perf_counter() - t0
    summary = json.loads((out / "summary.json").read_text())
    rows = summary["tasks_at_run_time"]["tasks"]
    waits = [r["served_at"] - r["entered_at"] for r in rows if r["state"] == "served"]
    own = {t: spec["arrival"] for t, spec in summary["instance"]["tasks"].items()}
    done: dict[str, float] = {}
    for e in summary["allocation"]:
        if e["task"] in own and e.get("done_at") is not None:
            done[e["task"]] = min(done.get(e["task"], e["done_at"]), e["done_at"])
    base = [done[t] - own[t] for t in done]
    common = {"architecture": arch, "burst": n, "duration_s": duration,
              "lockstep_exact": summary["lockstep_exact"]}
    return [{**common, "figure": "submit_to_served", "served": len(waits), "of": n,
             **spread(waits), "counts": summary["tasks_at_run_time"]["counts"],
             "wall_s": round(wall, 1)},
            {**common, "figure": "baseline_instance_arrival_to_served", "served": len(base),
             "of": len(own), **spread(base)}]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--bursts", default="10,200")
    ap.add_argument("--architectures", default=",".join(
        sorted(a for a, c in architectures().items() if c.takes_submitted)))
    ap.add_argument("--duration", type=float, default=60.0)
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        for n in [int(x) for x in args.bursts.split(",")]:
            for arch in args.architectures.split(","):
                for row in run(arch, n, args.duration, Path(tmp)):
                    print(json.dumps(row), flush=True)


if __name__ == "__main__":
    main()
