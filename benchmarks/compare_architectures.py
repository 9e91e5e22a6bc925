"""ALLIANCE vs MURDOCH, the study of issue #25: `python benchmarks/compare_architectures.py`.

Runs `mrta experiment` once per mission × architecture — missions `patrol` and `delivery`,
architectures `alliance` and `murdoch` — over the same seeds and the same fault models, lockstep
at full speed (a run's outcome depends on its seed only), with the two architectures'
parameters matched through experiment overrides (the shipped packages are not touched):

    ALLIANCE  broadcast_rate 2 Hz, timeout_duration τ = 2 s
    MURDOCH   renewal_period 0.5 s (2 Hz), lease_timeout 2 s

— the same message budget for "I am still on it", the same silence before a teammate may take
over. Fault models (docs/delivery.md, "Fault grammar"), on each mission's robot doing a task:
none, crash, stall, partition, loss, latency.

Figures per mission × fault × architecture: mean ± half-width of the 95 % interval over seeds
(Student's t, `mean_ci`), and per mission × fault the paired difference ALLIANCE − MURDOCH
(same seed: same world, same random streams, same lost messages) with its interval.
  patrol:   first full allocation, takeover, coverage (share with exactly one robot), and
            coordination messages/s (what robots tell each other: Architecture.coordination)
  delivery: makespan, optimality, completed, mean waiting time, takeover, coordination msgs/s
All bus samples/s are shown beside the coordination rate.

What it rewrites — nothing else:
  * docs/comparison.md: the block between `<!-- table: begin -->` and `<!-- table: end -->`
    (the discussion around it is written by hand);
  * README.md: the block between `<!-- study: begin -->` and `<!-- study: end -->` (a short
    headline table).
`--quick` (a smoke run: 1 seed, faults none and crash, short runs) rewrites neither unless
`--write-docs` is given; every run writes its tables to OUTPUT/tables.md. One JSON line per
figure on stdout.

    python benchmarks/compare_architectures.py --jobs 2 --output /tmp/study   # the full study
    --seeds 1 2 3 --duration 60 --missions delivery --faults none stall --quick
"""

from __future__ import annotations

import argparse
import csv
import json
import math
import re
import sys
import tempfile
from dataclasses import dataclass
from pathlib import Path

import yaml

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from mrta_supervisor.experiment import mean_ci, run_experiment  # noqa: E402

ARCHITECTURES = {"ALLIANCE": "alliance", "MURDOCH": "murdoch"}  # title → mrta.architectures
# the same message budget and the same silence (issue #25): ALLIANCE's heartbeat against
# MURDOCH's lease renewal, τ against the lease
MATCHED = {"alliance": {"robot*.broadcast_rate": 2.0, "robot*.timeout_duration": 2.0},
           "murdoch": {"robot*.renewal_period": 0.5, "robot*.lease_timeout": 2.0}}
FAULT_MODELS = ("none", "crash", "stall", "partition", "loss", "latency")
TABLE = ("<!-- table: begin -->", "<!-- table: end -->")
STUDY = ("<!-- study: begin -->", "<!-- study: end -->")


@dataclass(frozen=True)
class Metric:
    key: str            # a results.csv column, or "coverage" (mean of the tasks' exactly_one)
    title: str
    scale: float = 1.0  # shown × scale (shares as %)
    digits: int = 2
    faults_only: bool = False  # meaningful only after a robot's fault (the takeover)


@dataclass(frozen=True)
class Mission:
    application: str
    duration: float       # simulated s per run
    quick_duration: float
    faults: dict[str, str]
    metrics: tuple[Metric, ...]


COORDINATION = Metric("coordination_messages_per_second", "coordination msgs/s", digits=1)
TAKEOVER = Metric("takeover_seconds", "takeover (s)", faults_only=True)
MISSIONS = {
    # robot2 holds border_protection from 0.6 s in every seed; patrol's φ (600 s) is longer
    # than any run, so a stall there is invisible to both architectures (docs/comparison.md)
    "patrol": Mission("patrol", 60.0, 30.0, {
        "none": "none", "crash": "robot2@20", "stall": "stall:robot2@20",
        "partition": "partition:robot2@20+10", "loss": "loss:0.2",
        "latency": "latency:0.3±0.2"},
        (Metric("first_full_allocation", "first full allocation (s)"), TAKEOVER,
         Metric("coverage", "coverage, exactly one (%)", scale=100, digits=1), COORDINATION)),
    # robot1 drives to t1 (lift; robot3, idle, can lift too) from ≈ 2.4 s; its φ for t1 is
    # 42.1 s, so a stall is taken over by ALLIANCE near 45 s and served by ≈ 65 s
    "delivery": Mission("delivery", 80.0, 40.0, {
        "none": "none", "crash": "robot1@5", "stall": "stall:robot1@5",
        "partition": "partition:robot1@5+10", "loss": "loss:0.2",
        "latency": "latency:0.3±0.2"},
        (Metric("metrics.makespan", "makespan (s)"),
         Metric("metrics.optimality", "optimality", digits=3),
         Metric("metrics.completed", "completed", digits=2),
         Metric("metrics.mean_waiting_time", "mean waiting (s)"), TAKEOVER, COORDINATION)),
}
# the README's headline: (mission, fault, metric key)
HEADLINE = (("patrol", "crash", "takeover_seconds"),
            ("patrol", "none", "coordination_messages_per_second"),
            ("delivery", "none", "metrics.optimality"),
            ("delivery", "none", "metrics.makespan"),
            ("delivery", "stall", "metrics.completed"),
            ("delivery", "latency", "metrics.makespan"))


def value(row: dict, key: str) -> float | None:
    """The metric of one run (None: not measured, e.g. no makespan when a task never ended)."""
    if row.get("status") != "ok":
        return None
    if key == "coverage":
        shares = [float(v) for k, v in row.items()
                  if k.endswith(".exactly_one") and v not in ("", None)]
        return sum(shares) / len(shares) if shares else None
    v = row.get(key)
    return None if v in ("", None) else float(v)


def fmt(m: float, h: float, metric: Metric, n: int | None = None) -> str:
    if math.isnan(m):
        return "–"
    d = metric.digits
    text = f"{m * metric.scale:.{d}f}" + ("" if math.isnan(h) else f" ± {h * metric.scale:.{d}f}")
    return text + ("" if n is None else f" (n={n})")


def by_seed(rows: list[dict], fault: str, key: str) -> dict[int, float]:
    out = {}
    for r in rows:
        if r["failure"] == fault:
            v = value(r, key)
            if v is not None:
                out[int(r["seed"])] = v
    return out


def paired(a: dict[int, float], b: dict[int, float]) -> tuple[float, float, int]:
    """ALLIANCE − MURDOCH over the seeds both measured: mean, 95 % half-width, pairs."""
    diffs = [a[s] - b[s] for s in sorted(a.keys() & b.keys())]
    m, h = mean_ci(diffs)
    return m, h, len(diffs)


def mission_table(name: str, mission: Mission, faults: list[str],
                  results: dict[str, list[dict]]) -> list[str]:
    ms = mission.metrics
    lines = [f"### {name}", "",
             "| fault | architecture | runs ok | " + " | ".join(m.title for m in ms)
             + " | all samples/s |", "| --- | --- | --- |" + " --- |" * (len(ms) + 1)]
    for fault in faults:
        spec = mission.faults[fault]
        for title, arch in ARCHITECTURES.items():
            rows = [r for r in results[arch] if r["failure"] == spec]
            ok = [r for r in rows if r["status"] == "ok"]
            cells = []
            for m in ms:
                xs = list(by_seed(rows, spec, m.key).values())
                if m.faults_only and fault in ("none", "loss", "latency"):
                    cells.append("–")
                elif m.faults_only:  # taken over in n of the runs
                    cells.append(fmt(*mean_ci(xs), m) + f" ({len(xs)}/{len(ok)})")
                else:
                    cells.append(fmt(*mean_ci(xs), m))
                print(json.dumps({"mission": name, "fault": spec, "architecture": title,
                                  "figure": m.key, "mean": _num(mean_ci(xs)[0]),
                                  "half_width": _num(mean_ci(xs)[1]), "n": len(xs)}),
                      flush=True)
            total = mean_ci(list(by_seed(rows, spec, "messages_per_second").values()))
            lines.append(f"| {spec} | {title} | {len(ok)}/{len(rows)} | " + " | ".join(cells)
                         + f" | {fmt(*total, Metric('', '', digits=0))} |")
    lines += ["", f"Paired differences ALLIANCE − MURDOCH ({name}; same seed; mean ± 95 % "
                  "half-width, n = pairs where both measured it):", "",
              "| fault | " + " | ".join(m.title for m in ms) + " |",
              "| --- |" + " --- |" * len(ms)]
    for fault in faults:
        spec = mission.faults[fault]
        cells = []
        for m in ms:
            d = paired(by_seed(results["alliance"], spec, m.key),
                       by_seed(results["murdoch"], spec, m.key))
            cells.append("–" if d[2] == 0 or (m.faults_only and fault in ("none", "loss",
                                                                          "latency"))
                         else fmt(d[0], d[1], m, d[2]))
            print(json.dumps({"mission": name, "fault": spec, "figure": m.key,
                              "paired_alliance_minus_murdoch": _num(d[0]),
                              "half_width": _num(d[1]), "pairs": d[2]}), flush=True)
        lines.append(f"| {spec} | " + " | ".join(cells) + " |")
    return lines + [""]


def headline(results: dict[str, dict[str, list[dict]]], faults: dict[str, list[str]]) -> list[str]:
    lines = ["| mission | fault | figure | ALLIANCE | MURDOCH | ALLIANCE − MURDOCH (paired) |",
             "| --- | --- | --- | --- | --- | --- |"]
    for name, fault, key in HEADLINE:
        if name not in results or fault not in faults[name]:
            continue
        mission = MISSIONS[name]
        metric = next(m for m in mission.metrics if m.key == key)
        spec = mission.faults[fault]
        a = by_seed(results[name]["alliance"], spec, key)
        b = by_seed(results[name]["murdoch"], spec, key)
        lines.append(f"| {name} | {spec} | {metric.title} | {fmt(*mean_ci(list(a.values())), metric)}"
                     f" | {fmt(*mean_ci(list(b.values())), metric)} | {fmt(*paired(a, b)[:2], metric)} (n={len(a.keys() & b.keys())}) |")
    return lines


def _num(x: float) -> float | None:
    return None if math.isnan(x) else round(x, 4)


def replace_block(path: Path, markers: tuple[str, str], text: str) -> None:
    """Rewrite what lies between the two markers of `path`; refuse a file without them (a
    study's tables are never appended somewhere unexpected)."""
    doc = path.read_text()
    begin, end = markers
    if begin not in doc or end not in doc:
        raise SystemExit(f"{path}: no {begin} … {end} block to rewrite")
    path.write_text(re.sub(re.escape(begin) + ".*?" + re.escape(end),
                           lambda _: f"{begin}\n{text}\n{end}", doc, flags=re.S))


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seeds", type=int, nargs="+", default=None,
                    help="seeds (default 1 … 10; --quick: 1)")
    ap.add_argument("--duration", type=float, default=None,
                    help="simulated s per run, every mission (default: patrol 60, delivery 80; "
                         "--quick: 30, 40)")
    ap.add_argument("--missions", nargs="+", choices=sorted(MISSIONS), default=sorted(MISSIONS))
    ap.add_argument("--faults", nargs="+", choices=FAULT_MODELS, default=None,
                    help="fault models (default: all; --quick: none crash)")
    ap.add_argument("--jobs", type=int, default=2, help="runs at once")
    ap.add_argument("--output", type=Path, default=None, help="runs and tables (default: a tmp dir)")
    ap.add_argument("--quick", action="store_true", help="smoke run: 1 seed, 2 faults, short")
    ap.add_argument("--reuse", action="store_true",
                    help="make the tables from OUTPUT's results.csv files, running nothing")
    ap.add_argument("--write-docs", action=argparse.BooleanOptionalAction, default=None,
                    help="rewrite the blocks of docs/comparison.md and README.md "
                         "(default: yes, no with --quick)")
    ap.add_argument("--doc", type=Path, default=ROOT / "docs" / "comparison.md")
    ap.add_argument("--readme", type=Path, default=ROOT / "README.md")
    args = ap.parse_args()
    seeds = args.seeds or ([1] if args.quick else list(range(1, 11)))
    faults = args.faults or (["none", "crash"] if args.quick else list(FAULT_MODELS))
    write_docs = (not args.quick) if args.write_docs is None else args.write_docs
    out = args.output or Path(tempfile.mkdtemp(prefix="mrta-compare-"))
    out.mkdir(parents=True, exist_ok=True)

    results: dict[str, dict[str, list[dict]]] = {}
    durations = {}
    for name in args.missions:
        mission = MISSIONS[name]
        duration = args.duration or (mission.quick_duration if args.quick else mission.duration)
        durations[name] = duration
        results[name] = {}
        for arch in ARCHITECTURES.values():
            folder = out / f"{name}_{arch}"
            if args.reuse:
                with (folder / "results.csv").open(newline="") as f:
                    results[name][arch] = list(csv.DictReader(f))
            else:
                exp = out / f"{name}_{arch}.yaml"
                exp.write_text(yaml.safe_dump(
                    {"application": mission.application, "architecture": arch,
                     "duration": duration, "seeds": seeds,
                     "failures": [mission.faults[f] for f in faults],
                     "overrides": {k: [v] for k, v in MATCHED[arch].items()}},
                    sort_keys=False, allow_unicode=True))
                results[name][arch] = run_experiment(file=exp, output=folder, jobs=args.jobs)
            for r in results[name][arch]:
                if r["status"] != "ok":
                    print(json.dumps({"failed_run": r["run"], "mission": name,
                                      "architecture": arch, "error": r["error"]}), flush=True)

    matched = "; ".join(f"{t}: " + ", ".join(f"{k.split('.', 1)[1]} {v:g}"
                                             for k, v in MATCHED[a].items())
                        for t, a in ARCHITECTURES.items())
    n_seeds = f"{len(seeds)} seed{'s' if len(seeds) > 1 else ''}"
    lines = [f"{n_seeds} ({', '.join(map(str, seeds))}) × "
             f"{len(faults)} fault models per mission, "
             + ", ".join(f"{n} {d:g} simulated s" for n, d in durations.items())
             + f" per run, lockstep. Matched parameters — {matched}. Mean ± half-width of the "
             "95 % interval over seeds (Student's t); a takeover cell also says in how many "
             "runs the task was taken over. Coordination: samples/s robots send each other "
             "(ALLIANCE: its broadcasts; MURDOCH: announcements, bids, awards, claims, "
             "releases); all samples/s: everything on the bus.", ""]
    for name in args.missions:
        lines += mission_table(name, MISSIONS[name], faults, results[name])
    table = "\n".join(lines).rstrip()
    short = "\n".join([f"{n_seeds} per cell, lockstep, matched parameters "
                       "([docs/comparison.md](docs/comparison.md) has every figure).", ""]
                      + headline(results, {n: faults for n in args.missions}))
    (out / "tables.md").write_text(table + "\n\n" + short + "\n")
    if write_docs:
        replace_block(args.doc, TABLE, table)
        replace_block(args.readme, STUDY, short)
    print(json.dumps({"tables": str(out / "tables.md"), "runs": str(out),
                      "docs_rewritten": [str(args.doc), str(args.readme)] if write_docs else []}),
          flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
