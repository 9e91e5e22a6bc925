"""ALLIANCE vs MURDOCH, the comparison study: `python benchmarks/compare_architectures.py`.

Runs `mrta experiment` once per mission × architecture — missions `patrol` and `delivery`,
architectures `alliance` and `murdoch` — over the same seeds and the same fault models, lockstep
at full speed (a run's outcome depends on its seed only), with the two architectures'
parameters matched through experiment overrides (the shipped packages are not touched):

    ALLIANCE  broadcast_rate 2 Hz, timeout_duration τ = 2 s
    MURDOCH   renewal_period 0.5 s (2 Hz), lease_timeout 2 s

— the same message budget for "I am still on it", the same silence before a teammate may take
over. Fault models (docs/delivery.md, "Fault grammar"), on each mission's robot doing a task:
none, crash, stall, partition, loss, latency.

The tables are the experiment report's (mrta_supervisor.report_md, docs/statistics.md): both
architectures' results.csv rows of a mission go into OUTPUT/<mission>/results.csv, and the
report made from it — per cell the mean with its 95 % bootstrap interval, runs missing a metric
counted apart, identical runs said in words; ALLIANCE − MURDOCH paired by seed with its
bootstrap interval, Wilcoxon p (Holm-adjusted), A12 and the probability of improvement — is
OUTPUT/<mission>/summary.md, cells.csv, comparisons.csv and its plots. OUTPUT/tables.md holds
both missions' tables and the README's headline; one JSON line per figure goes to stdout.
  patrol:   first full allocation, takeover, coverage per task (share with exactly one robot),
            coordination messages/s (what robots tell each other: Architecture.coordination)
  delivery: makespan, optimality, completed, mean waiting time, takeover, coordination msgs/s

It writes nothing outside OUTPUT unless asked: `--write-docs` rewrites the block between
`<!-- table: begin -->` and `<!-- table: end -->` of docs/comparison.md (the discussion around
it is written by hand) and the README's `<!-- study: begin -->` … `<!-- study: end -->`
headline.

    python benchmarks/compare_architectures.py --jobs 2 --output /tmp/study   # the full study
    --seeds 1 2 3 --duration 60 --missions delivery --faults none stall --quick
    --reuse --output /tmp/study --write-docs    # the tables again from its results, into docs
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

from mrta_supervisor.experiment import run_experiment  # noqa: E402
from mrta_supervisor.report import Options, Report  # noqa: E402
from mrta_supervisor.report_md import brief, interval_text, num, p_text, share, write_report  # noqa: E402
from mrta_supervisor.results import write_csv  # noqa: E402

ARCHITECTURES = {"ALLIANCE": "alliance", "MURDOCH": "murdoch"}  # title → mrta.architectures
BASELINE = "murdoch"  # paired differences read ALLIANCE − MURDOCH
# the same message budget and the same silence: ALLIANCE's heartbeat against
# MURDOCH's lease renewal, τ against the lease
MATCHED = {"alliance": {"robot*.broadcast_rate": 2.0, "robot*.timeout_duration": 2.0},
           "murdoch": {"robot*.renewal_period": 0.5, "robot*.lease_timeout": 2.0}}
FAULT_MODELS = ("none", "crash", "stall", "partition", "loss", "latency")
TABLE = ("<!-- table: begin -->", "<!-- table: end -->")
STUDY = ("<!-- study: begin -->", "<!-- study: end -->")
COVERAGE = "*.exactly_one"  # every task's coverage column of the results


@dataclass(frozen=True)
class Mission:
    application: str
    duration: float       # simulated s per run
    quick_duration: float
    faults: dict[str, str]
    metrics: tuple[str, ...]  # results.csv columns, COVERAGE for every task's


COORDINATION = "coordination_messages_per_second"
MISSIONS = {
    # robot2 holds border_protection from 0.6 s in every seed; patrol's φ (600 s) is longer
    # than any run, so a stall there is invisible to both architectures (docs/comparison.md)
    "patrol": Mission("patrol", 60.0, 30.0, {
        "none": "none", "crash": "robot2@20", "stall": "stall:robot2@20",
        "partition": "partition:robot2@20+10", "loss": "loss:0.2",
        "latency": "latency:0.3±0.2"},
        ("first_full_allocation", "takeover_seconds", COVERAGE, COORDINATION)),
    # robot1 drives to t1 (lift; robot3, idle, can lift too) from ≈ 2.4 s; its φ for t1 is
    # 42.1 s, so a stall is taken over by ALLIANCE near 45 s and served by ≈ 65 s
    "delivery": Mission("delivery", 80.0, 40.0, {
        "none": "none", "crash": "robot1@5", "stall": "stall:robot1@5",
        "partition": "partition:robot1@5+10", "loss": "loss:0.2",
        "latency": "latency:0.3±0.2"},
        ("metrics.makespan", "metrics.optimality", "metrics.completed",
         "metrics.mean_waiting_time", "takeover_seconds", COORDINATION)),
}
# the README's headline: (mission, fault, metric column)
HEADLINE = (("patrol", "crash", "takeover_seconds"),
            ("patrol", "none", COORDINATION),
            ("delivery", "none", "metrics.optimality"),
            ("delivery", "none", "metrics.makespan"),
            ("delivery", "stall", "metrics.completed"),
            ("delivery", "latency", "metrics.makespan"))


def combined(folder: Path, mission: Mission, results: dict[str, list[dict]]) -> Path:
    """Both architectures' rows of one mission as one results.csv, each row naming its
    architecture and the mission's application (results written before those columns were
    get them here), so the report pairs ALLIANCE's runs with MURDOCH's of the same seed."""
    rows = []
    for arch, arch_rows in results.items():
        for r in arch_rows:
            rows.append({"architecture": arch, "application": mission.application, **r})
    folder.mkdir(parents=True, exist_ok=True)
    write_csv(folder / "results.csv", rows, [])
    return folder / "results.csv"


def metrics_of(mission: Mission, path: Path) -> tuple[str, ...]:
    with path.open(newline="") as f:
        columns = next(csv.reader(f))
    out = []
    for m in mission.metrics:
        out += sorted(c for c in columns if c.endswith(".exactly_one")) if m == COVERAGE else [m]
    return tuple(out)


def mission_tables(name: str, folder: Path) -> list[str]:
    """The mission's report (its summary.md), headings one level down, for tables.md."""
    text = (folder / "summary.md").read_text()
    body = text.split("\n", 1)[1]  # its title: replaced by the mission's
    return [f"### {name}", ""] + [("#" + line if line.startswith("#") else line)
                                  for line in body.splitlines()]


def json_lines(name: str, report: Report) -> None:
    for f in report.figures:
        d, i = f.figures, f.figures.interval
        print(json.dumps({"mission": name, "fault": f.cell.value("failure"),
                          "architecture": f.cell.value("architecture"), "figure": f.metric,
                          "n": d.n, "missing": d.missing, "mean": _num(d.mean),
                          "boot_low": _num(i.low) if i else None,
                          "boot_high": _num(i.high) if i else None,
                          "identical": d.identical}), flush=True)
    for c in report.comparisons:
        i = c.interval
        print(json.dumps({"mission": name, "fault": c.group.removeprefix("fail="),
                          "figure": c.metric, "alliance_minus_murdoch": _num(c.mean_difference),
                          "boot_low": _num(i.low) if i else None,
                          "boot_high": _num(i.high) if i else None, "pairs": c.pairs,
                          "wilcoxon_p": c.p, "holm_p": c.p_holm, "a12": _num(c.a12),
                          "improvement": c.improvement}), flush=True)


def headline(reports: dict[str, Report], faults: dict[str, list[str]]) -> list[str]:
    lines = ["| mission | fault | figure | ALLIANCE | MURDOCH | ALLIANCE − MURDOCH (paired) |",
             "| --- | --- | --- | --- | --- | --- |"]
    for name, fault, metric in HEADLINE:
        report = reports.get(name)
        if report is None or fault not in faults[name] or metric not in report.metrics:
            continue
        spec = MISSIONS[name].faults[fault]
        cells = {c.value("architecture"): c for c in report.cells if c.value("failure") == spec}
        figures = [brief(report.figure(cells[a], metric), metric) if a in cells else "–"
                   for a in ARCHITECTURES.values()]
        comp = next((c for c in report.comparisons
                     if c.metric == metric and c.group == f"fail={spec}"), None)
        diff = "–" if comp is None or comp.pairs == 0 else (
            f"{num(comp.mean_difference, metric)} "
            + ("(identical in every pair" if comp.identical else
               f"{interval_text(comp.interval, metric)} (p = {p_text(comp.p_holm)}, "
               f"A12 = {share(comp.a12)}") + f", n = {comp.pairs})")
        lines.append(f"| {name} | {spec} | {metric.removeprefix('metrics.')} | "
                     + " | ".join(figures) + f" | {diff} |")
    return lines


def _num(x: float) -> float | None:
    return None if x is None or math.isnan(x) else round(x, 4)


def replace_block(path: Path, markers: tuple[str, str], text: str) -> None:
    """Rewrite what lies between the two markers of `path`; refuse a file without them (a
    study's tables are never appended somewhere unexpected)."""
    doc = path.read_text()
    begin, end = markers
    if begin not in doc or end not in doc:
        raise SystemExit(f"{path}: no {begin} … {end} block to rewrite")
    path.write_text(re.sub(re.escape(begin) + ".*?" + re.escape(end),
                           lambda _: f"{begin}\n{text}\n{end}", doc, flags=re.S))


def main(argv: list[str] | None = None) -> int:
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
    ap.add_argument("--no-plots", action="store_true", help="no pictures, runs' nor report's")
    ap.add_argument("--write-docs", action="store_true",
                    help="also rewrite the blocks of docs/comparison.md and README.md "
                         "(default: write only into OUTPUT)")
    ap.add_argument("--doc", type=Path, default=ROOT / "docs" / "comparison.md")
    ap.add_argument("--readme", type=Path, default=ROOT / "README.md")
    args = ap.parse_args(argv)
    seeds = args.seeds or ([1] if args.quick else list(range(1, 11)))
    faults = args.faults or (["none", "crash"] if args.quick else list(FAULT_MODELS))
    out = args.output or Path(tempfile.mkdtemp(prefix="mrta-compare-"))
    out.mkdir(parents=True, exist_ok=True)

    reports: dict[str, Report] = {}
    durations = {}
    lines: list[str] = []
    for name in args.missions:
        mission = MISSIONS[name]
        duration = args.duration or (mission.quick_duration if args.quick else mission.duration)
        durations[name] = duration
        results: dict[str, list[dict]] = {}
        for arch in ARCHITECTURES.values():
            folder = out / f"{name}_{arch}"
            if args.reuse:
                with (folder / "results.csv").open(newline="") as f:
                    results[arch] = list(csv.DictReader(f))
            else:
                exp = out / f"{name}_{arch}.yaml"
                exp.write_text(yaml.safe_dump(
                    {"application": mission.application, "architecture": arch,
                     "duration": duration, "seeds": seeds,
                     "failures": [mission.faults[f] for f in faults],
                     "overrides": {k: [v] for k, v in MATCHED[arch].items()}},
                    sort_keys=False, allow_unicode=True))
                results[arch] = run_experiment(file=exp, output=folder, jobs=args.jobs,
                                               plots=not args.no_plots)
            for r in results[arch]:
                if r["status"] != "ok":
                    print(json.dumps({"failed_run": r["run"], "mission": name,
                                      "architecture": arch, "error": r["error"]}), flush=True)
        path = combined(out / name, mission, results)
        reports[name] = write_report(path, out / name, Options(
            baseline=BASELINE, metrics=metrics_of(mission, path), plots=not args.no_plots))
        json_lines(name, reports[name])
        lines += mission_tables(name, out / name) + [""]

    matched = "; ".join(f"{t}: " + ", ".join(f"{k.split('.', 1)[1]} {v:g}"
                                             for k, v in MATCHED[a].items())
                        for t, a in ARCHITECTURES.items())
    n_seeds = f"{len(seeds)} seed{'s' if len(seeds) > 1 else ''}"
    intro = (f"{n_seeds} ({', '.join(map(str, seeds))}) × {len(faults)} fault models per "
             "mission, " + ", ".join(f"{n} {d:g} simulated s" for n, d in durations.items())
             + f" per run, lockstep. Matched parameters — {matched}. Coordination: samples/s "
             "robots send each other (ALLIANCE: its broadcasts; MURDOCH: announcements, bids, "
             "awards, claims, releases). The statistics: docs/statistics.md.")
    table = "\n".join([intro, ""] + lines).rstrip()
    short = "\n".join([f"{n_seeds} per cell, lockstep, matched parameters; mean and 95 % "
                       "bootstrap interval, paired difference with its interval, Holm-adjusted "
                       "Wilcoxon p and A12 ([docs/comparison.md](docs/comparison.md) has every "
                       "figure).", ""]
                      + headline(reports, {n: faults for n in args.missions}))
    (out / "tables.md").write_text(table + "\n\n" + short + "\n")
    if args.write_docs:
        replace_block(args.doc, TABLE, table)
        replace_block(args.readme, STUDY, short)
    print(json.dumps({"tables": str(out / "tables.md"), "runs": str(out),
                      "docs_rewritten": [str(args.doc), str(args.readme)] if args.write_docs
                      else []}), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
