"""The architecture study's tables (benchmarks/compare_architectures.py), made from the
experiment report of each mission (mrta_supervisor.experiment.report): every figure is the report's — a
cell's mean and bootstrap interval, a paired comparison's difference, Holm-adjusted p and A12 —
laid out by fault, team size and architecture; nothing here computes a statistic."""

from __future__ import annotations

import json
import math
import re
from pathlib import Path

from mrta_zenoh.errors import ConfigError
from mrta_zenoh.files import write_text
from mrta_supervisor.experiment.report import Cell, Report
from mrta_supervisor.experiment.report_md import brief, interval_text, num, p_text, share, title

FAULT_ORDER = ("none", "crash", "stall", "partition", "loss", "latency", "range", "dispatcher")
# the fault models only some architectures can suffer, and what their other rows say instead
ONLY = {"dispatcher": ("central",)}
NOT_APPLICABLE = {"dispatcher": "n/a: no dispatcher to crash (not run)"}
# what a run did, compared with the faultless run of its instance and seed ("as without")
OUTCOME = ("metrics.completed", "metrics.makespan", "metrics.objective_minsum",
           "coordination_messages_per_second")
# the delivery table's columns: every objective beside its gap to the reference
SHOWN = ("metrics.completed", "metrics.makespan", "metrics.gap_minsum", "metrics.gap_makespan",
         "metrics.gap_flowtime", "takeover_seconds", "metrics.coordination_per_robot")
COMPARED = ("metrics.completed", "metrics.gap_minsum", "metrics.makespan",
            "coordination_messages_per_second")
HEADS = {"metrics.gap_minsum": "minsum gap (%)", "metrics.gap_makespan": "makespan gap (%)",
         "metrics.gap_flowtime": "flowtime gap (%)", "metrics.makespan": "makespan (s)",
         "metrics.completed": "completed",
         "metrics.coordination_per_robot": "coordination msgs/s per robot"}


MISSION_TITLES = {"delivery": "delivery", "walls": "delivery around walls"}


def head(metric: str) -> str:
    return HEADS.get(metric, title(metric))


def fault_kind(spec: str) -> str:
    """The fault model of a spec (FAULT_ORDER), whatever robot or role it names: its kind
    (`robot2@5` is a crash), and a crash of central's dispatcher its own model."""
    if spec == "none":
        return "none"
    kind, sep, subject = spec.partition(":")
    kind, subject = (kind, subject) if sep else ("crash", spec)
    return "dispatcher" if kind == "crash" and subject.startswith("dispatcher@") else kind


def size_of(cell: Cell) -> tuple[int, int]:
    return int(cell.value("n_robots") or 0), int(cell.value("n_tasks") or 0)


def ordered(report: Report, archs: list[str]) -> list[Cell]:
    """The cells by fault model, team size, task count, then the study's architecture order."""
    def key(c: Cell):
        arch = c.value("architecture")
        return (FAULT_ORDER.index(fault_kind(c.value("failure"))), size_of(c),
                archs.index(arch) if arch in archs else len(archs))
    return sorted(report.cells, key=key)


def references_line(report: Report) -> str:
    """Whether every instance's reference values are proven optimal, in the results' words."""
    flags = {r.get("metrics.reference_proven_optimal", "") for r in report.table.ok()}
    flags.discard("")
    if flags == {"True"}:
        return ("Every reference is proven optimal (exact, ≤ 10 tasks: docs/delivery.md, "
                "\"Reference values\").")
    return ("References: exact where `reference_proven_optimal` is True, otherwise OR-Tools' "
            "best found — never called optimal.")


def delivery_tables(report: Report, archs: list[str], intro: str,
                                    mission: str = "delivery") -> list[str]:
    """A mission's tables: one per fault model, a row per size and architecture (the cells of
    `report`), then the paired comparisons; `intro` says what the rows are a matrix of."""
    sizes = sorted({size_of(c) for c in report.cells})
    cols = [m for m in SHOWN if m in report.metrics]
    lines = [f"### {MISSION_TITLES.get(mission, mission)}", "", intro, ""]
    for fault in FAULT_ORDER:
        cells = [c for c in ordered(report, archs) if fault_kind(c.value("failure")) == fault]
        if not cells:
            continue
        shown = [m for m in cols if m != "takeover_seconds" or fault != "none"]
        same = [] if fault == "none" else ["as without a fault"]
        lines += [f"#### {cells[0].value('failure')}", "",
                  "| N | M | architecture | runs ok | " + " | ".join(map(head, shown))
                  + "".join(f" | {x}" for x in same) + " |",
                  "| --- | --- | --- | --- |" + " --- |" * (len(shown) + len(same))]
        by_size = {size_of(c): c for c in cells}
        for n, m in sizes:
            for arch in archs:
                c = next((c for c in cells if size_of(c) == (n, m)
                          and c.value("architecture") == arch), None)
                if c is None and (n, m) in by_size and arch not in ONLY.get(fault, (arch,)):
                    lines.append(f"| {n} | {m} | {arch} | {NOT_APPLICABLE[fault]} |"
                                 + " – |" * (len(shown) + len(same)))
                if c is None:
                    continue
                lines.append(f"| {n} | {m} | {arch} | {len(c.ok)}/{len(c.rows)} | "
                             + " | ".join(brief(report.figure(c, x), x) for x in shown)
                             + "".join(f" | {as_without(report, c)}" for _ in same) + " |")
        lines.append("")
    if report.axis == "architecture":  # one architecture: nothing to pair
        lines += comparison_table(report) + [""]
    return lines + (pictures() if mission == "delivery" else [])


def as_without(report: Report, cell: Cell) -> str:
    """How many of the cell's runs ended exactly as the faultless run of the same
    architecture, instance and seed (OUTCOME: tasks completed, makespan, MinSum, coordination
    traffic) — a fault that changed nothing, in words rather than a statistic."""
    def outcome(row: dict[str, str]) -> tuple[str, ...]:
        return tuple(row.get(k, "") for k in OUTCOME)

    def key(row: dict[str, str]) -> tuple[str, ...]:
        return (row.get("architecture", ""), row.get("instance", ""), row.get("seed", ""))

    faultless = {key(r): outcome(r) for r in report.table.ok() if r.get("failure") == "none"}
    paired = [r for r in cell.ok if key(r) in faultless]
    if not paired:
        return "–"
    same = sum(outcome(r) == faultless[key(r)] for r in paired)
    return ("every run" if same == len(paired) else "none" if same == 0
            else f"{same} of {len(paired)}")


def comparison_table(report: Report) -> list[str]:
    lines = [f"#### Paired against {report.baseline}", "",
             f"Architecture − {report.baseline} over the same instance and seed: the mean "
             "difference and its bootstrap interval, Holm-adjusted Wilcoxon p (a family per "
             "metric), A12 (the chance a run of the other is larger).", "",
             "| cell | architecture | " + " | ".join(head(m) for m in COMPARED
                                                      if m in report.metrics) + " |",
             "| --- | --- |" + " --- |" * sum(m in report.metrics for m in COMPARED)]
    found: dict[tuple[str, str], dict[str, str]] = {}
    for c in report.comparisons:
        if c.metric in COMPARED:
            found.setdefault((c.group, c.other), {})[c.metric] = _difference(c)
    for (group, other), by_metric in found.items():
        lines.append(f"| {group} | {other} | " + " | ".join(
            by_metric.get(m, "–") for m in COMPARED if m in report.metrics) + " |")
    return lines


def _difference(c) -> str:
    if c.pairs == 0:
        return "– (no pair)"
    if c.identical:
        return f"{num(c.mean_difference, c.metric)} (identical, n = {c.pairs})"
    return (f"{num(c.mean_difference, c.metric)} {interval_text(c.interval, c.metric)} "
            f"p = {p_text(c.p_holm)}, A12 = {share(c.a12)}, n = {c.pairs}")


def pictures() -> list[str]:
    return ["Plots (the report's, `--write-docs` copies them): makespan, optimality (the "
            "reference over the achieved value of the architecture's own objective), the "
            "MinSum gap, tasks completed, coordination messages per second per robot and the "
            "takeover time against the team size, one line per architecture and fault; and "
            "the performance profiles of MinSum and of the makespan against the best "
            "architecture and the reference.", "",
            *(f"![{name[:-4]}](img/study/{name})" for name in (
                "team_size_metrics.makespan.png", "team_size_metrics.optimality.png",
                "team_size_metrics.gap_minsum.png", "team_size_metrics.completed.png",
                "team_size_metrics.coordination_per_robot.png",
                "team_size_takeover_seconds.png", "profile_metrics.objective_minsum.png",
                "profile_metrics.makespan.png"))]


def mission_tables(name: str, folder: Path) -> list[str]:
    """The mission's report (its summary.md), headings one level down."""
    text = (folder / "summary.md").read_text()
    body = text.split("\n", 1)[1]  # its title: replaced by the mission's
    return [f"### {name}", ""] + [("#" + line if line.startswith("#") else line)
                                  for line in body.splitlines()]


# the README's headline: (mission, fault, N robots, tasks per robot, metric)
HEADLINE = (("delivery", "none", 5, 1, "metrics.gap_minsum"),
            ("delivery", "none", 5, 1, "metrics.makespan"),
            ("delivery", "none", 5, 1, "metrics.coordination_per_robot"),
            ("delivery", "none", 5, 2, "metrics.gap_minsum"),
            ("delivery", "none", 5, 2, "metrics.makespan"),
            ("delivery", "none", 10, 2, "metrics.gap_minsum"),
            ("delivery", "crash", 5, 1, "takeover_seconds"),
            ("delivery", "stall", 5, 1, "takeover_seconds"),
            ("delivery", "partition", 5, 1, "metrics.completed"),
            ("delivery", "loss", 5, 1, "metrics.makespan"),
            ("delivery", "latency", 5, 1, "metrics.makespan"),
            ("delivery", "range", 5, 1, "metrics.makespan"),
            ("delivery", "dispatcher", 5, 1, "metrics.completed"),
            ("walls", "none", 5, 1, "metrics.gap_minsum"),
            ("patrol", "crash", 0, 0, "takeover_seconds"))


def headline(reports: dict[str, Report], archs: list[str], intro: str) -> list[str]:
    """The README's short table (HEADLINE's rows) under `intro`, the words on what it is
    over."""
    lines = [intro, "",
             "| mission | fault | N / M | figure | " + " | ".join(archs) + " |",
             "| --- | --- | --- | --- |" + " --- |" * len(archs)]
    for mission, fault, n, per_robot, metric in HEADLINE:
        report = reports.get(mission)
        if report is None or metric not in report.metrics:
            continue
        cells = [c for c in report.cells if fault_kind(c.value("failure")) == fault]
        if mission != "patrol":
            cells = [c for c in cells if size_of(c) == (n, n * per_robot)]
        by_arch = {c.value("architecture"): c for c in cells}
        if not by_arch:
            continue
        spec = next(iter(by_arch.values())).value("failure")
        size = f"{n} / {n * per_robot}" if mission != "patrol" else "3 / 3"
        lines.append(f"| {mission} | {spec} | {size} | {head(metric)} | " + " | ".join(
            brief(report.figure(by_arch[a], metric), metric) if a in by_arch
            else "n/a" if a not in ONLY.get(fault, (a,)) else "not run"
            for a in archs) + " |")
    return lines


def json_lines(mission: str, report: Report) -> None:
    for f in report.figures:
        d, i = f.figures, f.figures.interval
        print(json.dumps({"mission": mission, "cell": f.cell.label,
                          "architecture": f.cell.value("architecture"), "figure": f.metric,
                          "n": d.n, "missing": d.missing, "mean": _num(d.mean),
                          "boot_low": _num(i.low) if i else None,
                          "boot_high": _num(i.high) if i else None,
                          "identical": d.identical}), flush=True)
    for c in report.comparisons:
        i = c.interval
        print(json.dumps({"mission": mission, "cell": c.group, "figure": c.metric,
                          "baseline": c.baseline, "other": c.other,
                          "other_minus_baseline": _num(c.mean_difference),
                          "boot_low": _num(i.low) if i else None,
                          "boot_high": _num(i.high) if i else None, "pairs": c.pairs,
                          "wilcoxon_p": c.p, "holm_p": c.p_holm, "a12": _num(c.a12),
                          "improvement": c.improvement}), flush=True)


def _num(x: float | None) -> float | None:
    return None if x is None or math.isnan(x) else round(x, 4)


def replace_block(path: Path, markers: tuple[str, str], text: str) -> None:
    """Rewrite what lies between the two markers of `path`; refuse a file without them (a
    study's tables are never appended somewhere unexpected)."""
    doc = path.read_text()
    begin, end = markers
    if begin not in doc or end not in doc:
        raise ConfigError(f"no {begin} … {end} block to rewrite", file=str(path))
    write_text(path, re.sub(re.escape(begin) + ".*?" + re.escape(end),
                           lambda _: f"{begin}\n{text}\n{end}", doc, flags=re.S))
