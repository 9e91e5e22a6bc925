"""ALLIANCE vs MURDOCH on the same patrol mission: `python benchmarks/compare_architectures.py`.

Runs `mrta experiment` twice — application `patrol` under `alliance` and under `murdoch`
— over the same seeds and failure scenarios, lockstep at full speed (each run's outcome depends
on its seed only), then prints one JSON line per figure and rewrites the table between the
markers of docs/comparison.md (the discussion around it is written by hand).

Figures per architecture and failure: time to the first full allocation (every task held), the
takeover time after the robot's death, the share of the run each task was covered by exactly
one / no / more than one robot, and bus samples per simulated second (all, and the
architecture's own coordination traffic).

    --seeds 1 2 3  --duration 90  --failures none robot2@30 robot1@30  --jobs 2  --output DIR
"""

from __future__ import annotations

import argparse
import json
import math
import re
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from mrta_supervisor.experiment import mean_ci, run_experiment  # noqa: E402

ARCHITECTURES = {"ALLIANCE": "alliance", "MURDOCH": "murdoch"}  # title → mrta.architectures name
TASKS = ("wander", "border_protection", "report")
BEGIN, END = "<!-- table: begin -->", "<!-- table: end -->"


def fmt(m: float, h: float, digits: int = 2) -> str:
    if math.isnan(m):
        return "–"
    return f"{m:.{digits}f}" + ("" if math.isnan(h) else f" ± {h:.{digits}f}")


def numbers(rows, key):
    return [float(r[key]) for r in rows if r.get(key) not in ("", None)]


def main() -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--seeds", type=int, nargs="+", default=[1, 2, 3])
    ap.add_argument("--duration", type=float, default=90.0)
    ap.add_argument("--failures", nargs="+", default=["none", "robot2@30", "robot1@30"])
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--output", type=Path, default=None)
    ap.add_argument("--doc", type=Path, default=ROOT / "docs" / "comparison.md")
    args = ap.parse_args()
    out = args.output or Path(tempfile.mkdtemp(prefix="mrta-compare-"))
    out.mkdir(parents=True, exist_ok=True)
    results: dict[str, list[dict]] = {}
    for arch, name in ARCHITECTURES.items():
        exp = out / f"patrol_{name}.yaml"
        exp.write_text(f"application: patrol\narchitecture: {name}\nduration: {args.duration}\n"
                       f"seeds: {json.dumps(args.seeds)}\nfailures: {json.dumps(args.failures)}\n")
        results[arch] = run_experiment(file=exp, output=out / name, jobs=args.jobs)
    lines = [f"{len(args.seeds)} seeds ({', '.join(map(str, args.seeds))}) × "
             f"{len(args.failures)} failure scenarios, {args.duration:g} simulated s each, "
             "lockstep. Mean ± half-width of the 95 % interval over seeds. Coverage: share of "
             "the run with exactly one / no / more than one robot on the task.", "",
             "| architecture | failure | runs ok | first full allocation (s) | takeover (s) | "
             + " | ".join(f"{t} 1 / 0 / >1 (%)" for t in TASKS)
             + " | samples/s (coordination) |",
             "| --- | --- | --- | --- | --- | " + " | ".join("---" for _ in TASKS) + " | --- |"]
    for failure in args.failures:
        for arch, rows in results.items():
            rs = [r for r in rows if r["failure"] == failure]
            ok = [r for r in rs if r["status"] == "ok"]
            first = mean_ci(numbers(ok, "first_full_allocation"))
            take = numbers(ok, "takeover_seconds")
            take_ci = mean_ci(take)
            cover = []
            for t in TASKS:
                parts = [mean_ci(numbers(ok, f"{t}.{k}"))[0] * 100
                         for k in ("exactly_one", "none", "more_than_one")]
                cover.append(" / ".join("–" if math.isnan(p) else f"{p:.0f}" for p in parts))
            rate = mean_ci(numbers(ok, "messages_per_second"))
            coord = mean_ci(numbers(ok, "coordination_messages_per_second"))
            taken = "–" if failure == "none" else (
                f"{fmt(*take_ci)} ({len(take)}/{len(ok)} taken over)")
            lines.append(f"| {arch} | {failure} | {len(ok)}/{len(rs)} | {fmt(*first)} | {taken} | "
                         + " | ".join(cover) + f" | {rate[0]:.0f} ({coord[0]:.1f}) |")
            for name, value in (("first_full_allocation_s", first[0]),
                                ("takeover_s", take_ci[0]),
                                ("samples_per_s", rate[0]),
                                ("coordination_samples_per_s", coord[0])):
                print(json.dumps({"figure": name, "architecture": arch, "failure": failure,
                                  "value": None if math.isnan(value) else round(value, 3),
                                  "runs": len(ok)}), flush=True)
            for r in rs:
                if r["status"] != "ok":
                    print(json.dumps({"failed_run": r["run"], "architecture": arch,
                                      "error": r["error"]}), flush=True)
    table = "\n".join(lines)
    doc = args.doc.read_text() if args.doc.exists() else f"{BEGIN}\n{END}\n"
    doc = re.sub(re.escape(BEGIN) + ".*?" + re.escape(END), f"{BEGIN}\n{table}\n{END}", doc,
                 flags=re.S)
    args.doc.write_text(doc)
    print(json.dumps({"table": str(args.doc), "runs": str(out)}), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
