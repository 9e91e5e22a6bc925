"""The report's files: summary.md for people, cells.csv and comparisons.csv for programs (full
precision: a float's shortest exact text), and `write_report`, the one function both
`mrta experiment` and `mrta experiment report` end with.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from mrta_zenoh.files import write_text
from mrta_zenoh.yamlfile import plural

from . import stats
from .provenance import CODE_COLUMN, revisions
from .report import Cell, Options, Report, build
from .results import read_results, title, write_csv

SHARE = (".exactly_one", ".none", ".more_than_one")  # shares of the run, shown in %
SMALL = 5  # below this many values a bootstrap interval is at most the values' range
BETTER_WORDS = {stats.LOWER: "lower is better", stats.HIGHER: "higher is better",
                None: "which direction is better is not declared"}


@dataclass
class Precision:
    """What `--until-ci` asked and what it reached (api.py), for summary.md."""

    targets: dict[str, float]
    runs: int
    max_runs: int
    blocks: int
    missed: list[tuple[str, str, float | None]] = field(default_factory=list)  # cell, metric, hw
    stopped: bool = False  # a Ctrl-C ended the blocks, not the cap
    by: str = "new seeds"  # what a block after the file's own adds: seeds, or instances


def write_report(results: Path, output: Path | None = None, options: Options = Options(),
                 precision: Precision | None = None) -> Report:
    """summary.md, cells.csv, comparisons.csv and the plots of RESULTS (results.csv, or a folder
    holding one) into `output` (default: the results' folder)."""
    from .report_plots import plot_report

    results = Path(results)
    path = results / "results.csv" if results.is_dir() else results
    output = Path(output) if output is not None else path.parent
    report = build(read_results(path), options)
    write_text(output / "summary.md", summary_md(report, precision))
    write_cells_csv(report, output / "cells.csv")
    write_comparisons_csv(report, output / "comparisons.csv")
    if options.plots:
        plot_report(report, output)
    return report


# ------------------------------------------------------------------ text from results.csv
_MD_SPECIAL = re.compile(r"([\\`*|<>\[\]])")


def md(text: Any) -> str:
    """Text read from results.csv (a cell's label, an error, a column's name) as Markdown shows
    it: one line (a newline then `# Heading` stays in its cell, never a heading), the characters
    a table or Markdown would read as markup escaped — `x|<b>` is shown as written, never as a
    column or a tag (issue 51.5)."""
    return _MD_SPECIAL.sub(r"\\\1", " ".join(str(text).split()))


def code(text: Any) -> str:
    """`text` as a code span: one line, no backtick to end it early, pipes escaped for tables."""
    return "`" + " ".join(str(text).split()).replace("`", "'").replace("|", "\\|") + "`"


# ------------------------------------------------------------------ numbers as text
def scale_of(metric: str) -> tuple[float, str]:
    return (100.0, " %") if metric.endswith(SHARE) else (1.0, "")




def num(x: float | None, metric: str = "") -> str:
    if x is None or not math.isfinite(x):
        return "–"
    s, unit = scale_of(metric)
    x *= s
    digits = 3 if abs(x) < 1 and x != 0 and not unit else 2
    return (f"{x:,.0f}" if abs(x) >= 1000 else f"{x:.{digits}f}") + unit


def share(x: float | None) -> str:
    """A probability (A12, the probability of improvement), two decimals."""
    return "–" if x is None or not math.isfinite(x) else f"{x:.2f}"


def p_text(p: float | None) -> str:
    if p is None:
        return "–"
    return "< 0.001" if p < 0.001 else f"{p:.3f}"


def interval_text(i: stats.Interval | None, metric: str) -> str:
    return "–" if i is None else f"[{num(i.low, metric)}, {num(i.high, metric)}]"


def brief(f: stats.Describe, metric: str) -> str:
    """One cell of the overview: the mean and its bootstrap interval, or what stands instead."""
    if f.n == 0:
        return "–" + (f" (missing in {plural(f.missing, 'run')})" if f.missing else "")
    text = num(f.mean, metric)
    if f.identical:
        text += " (identical in every run)"
    elif f.n == 1:
        text += " (1 run)"
    else:
        text += " " + interval_text(f.interval, metric)
    if f.missing:
        text += f"; missing in {f.missing} of {f.n + f.missing}"
    return text


# ------------------------------------------------------------------ summary.md
def summary_md(report: Report, precision: Precision | None = None) -> str:
    rows = report.table.rows
    lines = [f"# {md(_headline(report))}", "", _intro(report), ""]
    lines += _overview(report) + [""] + _details(report) + _comparisons(report)
    if precision is not None:
        lines += _precision(report, precision)
    failed = [r for r in rows if r.get("status") != "ok"]
    if failed:
        lines += ["## Failed runs", "", "Left out of every figure above.", ""]
        lines += [f"- run {md(r.get('run', '?'))} ({md(_cell_of(report, r).label)}, seed "
                  f"{r['seed']}): {md(r.get('status'))}: {md(r.get('error', ''))}"
                  for r in failed]
    return "\n".join(lines).rstrip() + "\n"


def _single(report: Report, column: str) -> str | None:
    values = {r.get(column, "") for r in report.table.rows}
    return values.pop() if len(values) == 1 and "" not in values else None


def _headline(report: Report) -> str:
    app, arch = _single(report, "application"), _single(report, "architecture")
    duration = _single(report, "duration")
    what = (app or "experiment") + (f" under {arch}" if arch else "")
    runs = plural(len(report.table.rows), "run")
    return f"{what}: {runs}" + (f" of {float(duration):g} s" if duration else "")


def _intro(report: Report) -> str:
    seeds = sorted({int(r["seed"]) for r in report.table.rows})
    instances = sorted({report.instance(r) for r in report.table.rows})
    where = ("`instance` column" if "instance" in report.table.columns
             else "one per application: no `instance` column")
    return (f"Runs over seeds ({', '.join(map(str, seeds))}); "
            f"{plural(len(instances), 'instance')} ({where}); "
            f"{plural(len(report.cells), 'cell')}. Each figure is over the runs of a cell that "
            "ended well; a run without a value of a metric (no takeover when nothing failed, "
            "no makespan when a task was never served) is counted as missing, never as 0. "
            "Coverage: share of the run with exactly one robot on the task." + _code(report))


def _code(report: Report) -> str:
    """Which code made the rows (results.csv's `code`, provenance.py): one revision, or each
    with its count — rows of several revisions are a mix a reader should see — and the rows
    made before the column existed (blank: their provenance is kept elsewhere)."""
    counts = revisions(report.table.rows)
    named = {k: n for k, n in counts.items() if k}
    if not named:
        return ""
    said = (f"`{next(iter(named))}`" if len(named) == 1 else
            ", ".join(f"`{k}` ({plural(n, 'run')})" for k, n in named.items()))
    blank = counts.get("", 0)
    return (f" Code (`{CODE_COLUMN}` column): {said}"
            + (f"; {plural(blank, 'run')} from before rows named their code" if blank else "")
            + ".")


def _bootstrap_note(report: Report, intervals: list[stats.Interval | None]) -> str:
    methods = sorted({i.method for i in intervals if i is not None})
    return (f"Bootstrap: 95 % interval of the mean, {report.options.resamples:,} resamples, "
            f"seed {report.options.seed}; drawn here: {', '.join(methods) or 'none'} (BCa over "
            "the runs of a cell with one instance, percentile over instances then the seeds "
            "within each when it has several: docs/statistics.md).")


def _overview(report: Report) -> list[str]:
    ms = report.metrics
    lines = ["## Overview", "", "Mean and 95 % bootstrap interval per cell.", "",
             "| cell | runs (failed) | " + " | ".join(md(title(m)) for m in ms) + " |",
             "| --- | --- |" + " --- |" * len(ms)]
    for cell in report.cells:
        lines.append(f"| {md(cell.label)} | {len(cell.rows)} ({len(cell.rows) - len(cell.ok)}) | "
                     + " | ".join(brief(report.figure(cell, m), m) for m in ms) + " |")
    lines += ["", _bootstrap_note(report, [f.figures.interval for f in report.figures])]
    if any(2 <= f.figures.n < SMALL and not f.figures.identical for f in report.figures):
        lines += ["", f"A cell of fewer than {SMALL} runs: its bootstrap interval cannot be wider "
                      "than the range of its values and understates the uncertainty (the "
                      "Student's t interval in the tables below shows how much)."]
    return lines


def _details(report: Report) -> list[str]:
    lines = ["## Per metric", ""]
    for m in report.metrics:
        lines += [f"### {md(title(m))} — {code(m)}, {BETTER_WORDS[report.better[m]]}", "",
                  "| cell | n | missing | mean | median | IQR [Q1, Q3] | IQM | 95 % bootstrap "
                  "| 95 % Student's t |", "| --- |" + " --- |" * 8]
        for cell in report.cells:
            f = report.figure(cell, m)
            boot = ("identical in every run" if f.identical
                    else interval_text(f.interval, m))
            t = ("–" if math.isnan(f.t_half_width) else
                 f"[{num(f.mean - f.t_half_width, m)}, {num(f.mean + f.t_half_width, m)}]")
            iqr = "–" if f.n == 0 else f"{num(f.iqr, m)} [{num(f.q1, m)}, {num(f.q3, m)}]"
            lines.append(f"| {md(cell.label)} | {f.n} | {f.missing} | {num(f.mean, m)} | "
                         f"{num(f.median, m)} | {iqr} | {num(f.iqm, m)} | {boot} | {t} |")
        lines.append("")
    return lines


def _comparisons(report: Report) -> list[str]:
    if not report.comparisons:
        return []
    against = (f"each other {report.axis} against {code(report.baseline)}, within each cell of "
               "the other parameters" if report.axis
               else f"each cell against {code(report.baseline)}")
    lines = ["## Paired comparisons", "",
             f"Other − baseline, {against}, paired by instance and seed (the same world, "
             "random streams and faults). Differences: mean and 95 % bootstrap interval "
             f"(seed {report.options.seed}); Wilcoxon signed-rank p (exact for small n), "
             "Holm-adjusted within each metric's table; A12 = P(baseline < other) + ½ "
             "P(equal) over every pair of runs of the two cells; P(better): the share of "
             "matched pairs where the other did better, ties counted half.", ""]
    for m in report.metrics:
        rows = [c for c in report.comparisons if c.metric == m]
        lines += [f"### {md(title(m))} — {code(m)}, {BETTER_WORDS[report.better[m]]}", "",
                  "| cell | baseline → other | pairs | other − baseline | Wilcoxon p | Holm p "
                  "| A12 | P(better) |", "| --- |" + " --- |" * 7]
        for c in rows:
            diff = "–" if c.pairs == 0 else (
                f"{num(c.mean_difference, m)} (identical in every pair)" if c.identical else
                f"{num(c.mean_difference, m)} " + ("(1 pair)" if c.pairs == 1
                                                   else interval_text(c.interval, m)))
            lines.append(f"| {md(c.group) or '–'} | {md(c.baseline)} → {md(c.other)} | "
                         f"{c.pairs} | {diff} | "
                         f"{p_text(c.p)} | {p_text(c.p_holm)} | {share(c.a12)} | "
                         f"{share(c.improvement)} |")
        tested = sum(c.p is not None for c in rows)
        lines += ["", f"Holm family: the {plural(tested, 'comparison')} of {code(m)} with a p-value "
                      f"in this table ({len(rows) - tested} without one: no pair, or every "
                      "paired difference zero). " + _a12_words(report.better[m]), ""]
    return lines


def _a12_words(better: str | None) -> str:
    if better == stats.LOWER:
        return "Lower is better: A12 below 0.5 favours the other."
    if better == stats.HIGHER:
        return "Higher is better: A12 above 0.5 favours the other."
    return "No direction is declared for this metric: A12 says only which is larger."


def _precision(report: Report, p: Precision) -> list[str]:
    asked = ", ".join(f"{code(m)} ≤ {num(h, m)}" for m, h in p.targets.items())
    if not p.missed:
        return ["## Precision", "", f"Every cell reached the bootstrap half-width asked "
                f"({asked}) after {plural(p.blocks, 'block')}, {plural(p.runs, 'run')} "
                f"(each block after the file's own: {p.by}).", ""]
    lines = ["## Precision not reached", "",
             f"`--until-ci` asked for bootstrap half-widths {asked}; after "
             f"{plural(p.blocks, 'block')} (each after the file's own: {p.by}), "
             f"{plural(p.runs, 'run')} ("
             + ("stopped by the user" if p.stopped else f"the cap, --max-runs {p.max_runs:,}, "
                "leaves no room for another block") + ") these cells are wider:", "",
             "| cell | metric | half-width | asked |", "| --- | --- | --- | --- |"]
    for cell, m, hw in p.missed:
        lines.append(f"| {md(cell)} | {code(m)} | "
                     f"{'no interval (fewer than two values)' if hw is None else num(hw, m)} | "
                     f"{num(p.targets[m], m)} |")
    return lines + [""]


def _cell_of(report: Report, row: dict[str, str]) -> Cell:
    return next(c for c in report.cells if any(r is row for r in c.rows))


# ------------------------------------------------------------------ the CSV files
def _full(x: float | None) -> Any:
    return "" if x is None or (isinstance(x, float) and math.isnan(x)) else x


def write_cells_csv(report: Report, path: Path) -> None:
    params = [c for c in report.table.parameters if c != "instance"]
    rows = []
    for f in report.figures:
        d, i = f.figures, f.figures.interval
        row = {p: f.cell.value(p) for p in params}
        row.update({"cell": f.cell.label, "metric": f.metric, "better": report.better[f.metric]
                    or "", "runs": len(f.cell.rows), "failed": len(f.cell.rows) - len(f.cell.ok),
                    "n": d.n, "missing": d.missing, "mean": _full(d.mean),
                    "median": _full(d.median), "q1": _full(d.q1), "q3": _full(d.q3),
                    "iqr": _full(d.iqr), "iqm": _full(d.iqm),
                    "t_low": _full(d.mean - d.t_half_width), "t_high": _full(d.mean + d.t_half_width),
                    "boot_low": _full(i.low if i else (d.mean if d.identical else None)),
                    "boot_high": _full(i.high if i else (d.mean if d.identical else None)),
                    "boot_method": i.method if i else ("identical in every run" if d.identical
                                                       else ""),
                    "identical": d.identical})
        rows.append(row)
    write_csv(path, rows, [])


def write_comparisons_csv(report: Report, path: Path) -> None:
    rows = []
    for c in report.comparisons:
        i = c.interval
        rows.append({"cell": c.group, "metric": c.metric, "better": c.better or "",
                     "axis": report.axis or "cell", "baseline": c.baseline, "other": c.other,
                     "pairs": c.pairs, "mean_difference": _full(c.mean_difference),
                     "boot_low": _full(i.low if i else None),
                     "boot_high": _full(i.high if i else None),
                     "boot_method": i.method if i else "", "wilcoxon_p": _full(c.p),
                     "holm_p": _full(c.p_holm), "a12": _full(c.a12),
                     "improvement": _full(c.improvement)})
    fields = ["cell", "metric", "better", "axis", "baseline", "other", "pairs",
              "mean_difference", "boot_low", "boot_high", "boot_method", "wilcoxon_p", "holm_p",
              "a12", "improvement"]
    write_csv(path, rows, fields)
