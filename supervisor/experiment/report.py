"""An experiment's report, made from results.csv alone: the cells and their figures, the paired
comparisons, the performance profiles and the precision reached (stats.py computes; this module
groups the rows). `mrta experiment report DIR` and the end of `mrta experiment` both call
report_md.write_report, which writes summary.md, cells.csv, comparisons.csv and the plots
(report_plots.py).

Cells: the runs that share every parameter column (results.py) but the instance and the seed.
Within a cell, runs are grouped by instance (no `instance` column: one instance per
application, the `application` column) for the two-level bootstrap. Comparisons: when the results hold several architectures,
each other architecture against the baseline one within each cell of the other parameters,
paired by (instance, seed) — with the failure and the overrides fixed by the cell, that is the
same (instance, seed, failure); otherwise every cell against the baseline cell, paired the same
way. `--baseline` names the baseline (an architecture, or a cell's label); by default the first
in sorted order.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

from mrta_zenoh.errors import ConfigError
from mrta_zenoh.yamlfile import did_you_mean

from . import stats
from .results import INSTANCE, ResultsTable, column_named, kind
from ..mission.hook import Mission
from ..mission.summary import mission_hook

ARCHITECTURE = "architecture"
REFERENCE = "metrics.reference_"  # metrics.reference_X: the reference value of metrics.X
# the framework's measures and which way is better; an application's own (`metrics.*`) say so
# through their Mission's `better`
FRAMEWORK_BETTER = {"takeover_seconds": stats.LOWER, "first_full_allocation": stats.LOWER,
                    "messages": stats.LOWER, "messages_per_second": stats.LOWER,
                    "coordination_messages_per_second": stats.LOWER,
                    "namespace_messages_per_second": stats.LOWER}
COVERAGE = (".exactly_one", ".none", ".more_than_one")  # a task's coverage shares
# measured, but not what a table is for by default (redundant shares, raw counts, references)
NOT_BY_DEFAULT = (".none", ".more_than_one")
NOT_BY_DEFAULT_NAMES = ("messages", "messages_per_second", "namespace_messages_per_second",
                        "decisions")
# references; counts of each message kind; what injected faults did to the messages (the
# fault's dose, which shows it acted — asked for by name: `--metrics faults.lost`)
NOT_BY_DEFAULT_PREFIXES = (REFERENCE, "messages.", "faults.")


@dataclass(frozen=True)
class Options:
    baseline: str | None = None
    metrics: tuple[str, ...] | None = None   # None: every measured column with numbers
    seed: int = stats.SEED
    resamples: int = stats.RESAMPLES
    plots: bool = True


@dataclass
class Cell:
    key: tuple[tuple[str, str], ...]         # its parameters (all but instance and seed)
    label: str
    rows: list[dict[str, str]]               # every run of the cell, failed ones too

    @property
    def ok(self) -> list[dict[str, str]]:
        return [r for r in self.rows if r.get("status") == "ok"]

    def value(self, name: str) -> str:
        return dict(self.key).get(name, "")


@dataclass
class CellFigures:
    cell: Cell
    metric: str
    figures: stats.Describe


@dataclass
class Comparison:
    metric: str
    group: str                 # the cell of the other parameters ("" when cells are compared)
    baseline: str
    other: str
    pairs: int
    mean_difference: float     # other − baseline
    interval: stats.Interval | None
    p: float | None
    p_holm: float | None
    a12: float
    improvement: float | None  # None: the metric has no known better direction
    better: str | None
    identical: bool            # every paired difference the same (two pairs or more)


@dataclass
class Report:
    table: ResultsTable
    options: Options
    metrics: list[str]
    cells: list[Cell]
    figures: list[CellFigures]
    axis: str | None                       # the compared column (architecture), or None: cells
    variants: list[str]
    baseline: str | None
    comparisons: list[Comparison] = field(default_factory=list)
    better: dict[str, str | None] = field(default_factory=dict)

    def figure(self, cell: Cell, metric: str) -> stats.Describe:
        return next(f.figures for f in self.figures if f.cell is cell and f.metric == metric)

    def instance(self, row: dict[str, str]) -> str:
        return instance_of(self.table, row)


def instance_of(table: ResultsTable, row: dict[str, str]) -> str:
    """The row's instance: its `instance` column, or its application's one instance (the
    application as the experiment file names it: the same under every architecture)."""
    if INSTANCE in table.columns:
        return row[INSTANCE]
    return row.get("application", "")


def default_metrics(table: ResultsTable) -> list[str]:
    """Every measured column with a number in some run that ended well, but redundant shares,
    raw counts and reference values."""
    out = []
    for c in table.columns:
        if kind(c) != "measure" or c.endswith(NOT_BY_DEFAULT) or c in NOT_BY_DEFAULT_NAMES \
                or c.startswith(NOT_BY_DEFAULT_PREFIXES):
            continue
        if any(_is_number(r.get(c, "")) for r in table.ok()):
            out.append(c)
    return out


def _is_number(text: str) -> bool:
    try:
        return math.isfinite(float(text))
    except ValueError:
        return False


def better_of(table: ResultsTable, metric: str) -> str | None:
    """Which direction is better for `metric`: the framework's own measures, or what the
    mission of the rows (`mission` column) declares for its metrics; None: not known."""
    if metric in FRAMEWORK_BETTER:
        return FRAMEWORK_BETTER[metric]
    missions = sorted({r.get("mission", "") for r in table.rows} - {""})
    for suffix in COVERAGE:
        if metric.endswith(suffix):
            # as each mission declares (a mission not installed here: the framework's default);
            # missions that disagree, or one that declares none, give no direction (issue 51:
            # delivery's coverage was called "higher is better")
            said = {(mission_hook(m) or Mission).coverage_better.get(suffix[1:])
                    for m in missions or [""]}
            return said.pop() if len(said) == 1 else None
    name = metric.removeprefix("metrics.")
    for mission in missions:
        hook = mission_hook(mission)  # None: not installed here, the direction is not known
        declared = hook.better if hook is not None else {}
        if name in declared:
            return declared[name]
    return None


def cells_of(table: ResultsTable) -> list[Cell]:
    """The cells, labelled by the failure and every other parameter that varies (an
    architecture's own override, blank in another architecture's rows, only where it is set)."""
    params = [c for c in table.parameters if c != INSTANCE]
    varying = [c for c in params if len({r.get(c, "") for r in table.rows}) > 1]
    shown = [c for c in params if c == "failure" or (c in varying and c != ARCHITECTURE)]
    cells: dict[tuple, Cell] = {}
    for row in table.rows:
        key = tuple((c, row.get(c, "")) for c in params)
        if key not in cells:
            label = " ".join(("fail" if c == "failure" else c) + "=" + row[c]
                             for c in shown if row.get(c, "") != "") or "all runs"
            if ARCHITECTURE in varying:
                label = f"{row.get(ARCHITECTURE, '')}: {label}"
            cells[key] = Cell(key, label, [])
        cells[key].rows.append(row)
    return sorted(cells.values(), key=lambda c: c.label)


def shared_parameters(table: ResultsTable, axis: str) -> list[str]:
    """The parameters cells are matched on across the values of `axis`: all but the axis, the
    instance, and a parameter some value of the axis never sets — one architecture's own
    override (ALLIANCE's broadcast_rate, blank in MURDOCH's rows) is part of that architecture,
    not a condition both ran under."""
    by_value: dict[str, list[dict[str, str]]] = {}
    for row in table.rows:
        by_value.setdefault(row.get(axis, ""), []).append(row)
    return [c for c in table.parameters if c not in (axis, INSTANCE)
            and not any(all(r.get(c, "") == "" for r in rows) for rows in by_value.values())]


def values_by_instance(table: ResultsTable, cell: Cell, metric: str
                       ) -> tuple[dict[str, list[float]], int]:
    """The metric's values in the cell's runs that ended well, by instance (in order of first
    appearance), and how many of those runs lack it."""
    groups: dict[str, list[float]] = {}
    missing = 0
    for row in cell.ok:
        v = table.number(row, metric)
        if v is None:
            missing += 1
        else:
            groups.setdefault(instance_of(table, row), []).append(v)
    return groups, missing


def build(table: ResultsTable, options: Options = Options()) -> Report:
    """The report's figures for `table` (nothing written)."""
    if options.metrics is not None:  # by their column names or the names the tables print
        options = replace(options, metrics=tuple(column_named(m, table.columns)
                                                 for m in options.metrics))
        for m in options.metrics:
            table.check_metric(m)
    metrics = list(options.metrics) if options.metrics is not None else default_metrics(table)
    cells = cells_of(table)
    figures = []
    for cell in cells:
        for m in metrics:
            groups, missing = values_by_instance(table, cell, m)
            figures.append(CellFigures(cell, m, stats.describe(
                list(groups.values()), missing, options.seed, options.resamples)))
    archs = sorted({r.get(ARCHITECTURE, "") for r in table.rows} - {""})
    axis = ARCHITECTURE if len(archs) > 1 else None
    variants = archs if axis else [c.label for c in cells]
    baseline = _baseline(table, options.baseline, axis, variants)
    report = Report(table, options, metrics, cells, figures, axis, variants, baseline,
                    better={m: better_of(table, m) for m in metrics})
    if baseline is not None:
        report.comparisons = comparisons(report)
    return report


def _baseline(table: ResultsTable, asked: str | None, axis: str | None,
              variants: list[str]) -> str | None:
    if asked is None:
        return variants[0] if len(variants) > 1 else None
    if asked not in variants:
        what = "architecture" if axis else "cell"
        raise ConfigError(f"--baseline {asked!r}: not an {what} of these results"
                          + did_you_mean(asked, variants) + f"; they have {', '.join(variants)}",
                          file=str(table.path))
    return asked


def _groups(report: Report) -> dict[str, dict[str, Cell]]:
    """Cells by the group they are compared in (its label: the shared parameters that vary,
    and the failure), then by variant: the architecture — with its own parameters when it has
    several cells in the group (a sweep of one architecture's override) — or, without an
    architecture axis, the cell's label."""
    if not report.axis:
        return {"": {cell.label: cell for cell in report.cells}}
    axis, rows = report.axis, report.table.rows
    shared = shared_parameters(report.table, axis)
    shown = [c for c in shared if c == "failure" or len({r.get(c, "") for r in rows}) > 1]
    own = [c for c in report.table.parameters if c not in shared and c not in (axis, INSTANCE)]
    grouped: dict[str, list[Cell]] = {}
    for cell in report.cells:
        group = " ".join(("fail" if c == "failure" else c) + "=" + cell.value(c) for c in shown)
        grouped.setdefault(group, []).append(cell)
    out: dict[str, dict[str, Cell]] = {}
    for group, cells in grouped.items():
        for cell in cells:
            name = cell.value(axis)
            if sum(c.value(axis) == name for c in cells) > 1:
                name += " " + " ".join(f"{c}={cell.value(c)}" for c in own if cell.value(c))
            out.setdefault(group, {})[name] = cell
    return out


def _baseline_cell(report: Report, group: str, variants: dict[str, Cell]) -> Cell | None:
    """The group's cell of the baseline; a ConfigError when the baseline architecture has
    several there (its own sweep: which one is the baseline is the user's choice)."""
    if not report.axis:
        return variants.get(report.baseline)
    cells = [c for c in variants.values() if c.value(report.axis) == report.baseline]
    if len(cells) > 1:
        raise ConfigError(f"--baseline {report.baseline}: {len(cells)} cells of it in "
                          f"{group or 'these results'} ({', '.join(c.label for c in cells)}): "
                          "report them apart (--metrics, or a results.csv of one of them)",
                          file=str(report.table.path))
    return cells[0] if cells else None


def _pairs(report: Report, base: Cell, other: Cell, metric: str
           ) -> list[tuple[str, float, float]]:
    """(instance, baseline value, other value) for every (instance, seed) both cells ran well
    and measured."""
    def by_run(cell: Cell) -> dict[tuple[str, str], float]:
        out: dict[tuple[str, str], float] = {}
        for row in cell.ok:
            key = (report.instance(row), row["seed"])
            if key in out:
                raise report.table.error(row, "seed", f"a second run of cell {cell.label!r} "
                                         f"with instance {key[0]!r} and seed {key[1]}")
            v = report.table.number(row, metric)
            if v is not None:
                out[key] = v
        return out
    a, b = by_run(base), by_run(other)
    return [(k[0], a[k], b[k]) for k in sorted(a.keys() & b.keys())]


def comparisons(report: Report) -> list[Comparison]:
    """Every other variant against the baseline, per group and metric; Holm's adjustment over
    each metric's comparisons that have a p-value."""
    out: list[Comparison] = []
    o = report.options
    for metric in report.metrics:
        family: list[Comparison] = []
        better = report.better[metric]
        for group, variants in _groups(report).items():
            base = _baseline_cell(report, group, variants)
            if base is None:
                continue
            for name, cell in variants.items():
                if cell is base:
                    continue
                pairs = _pairs(report, base, cell, metric)
                d = [y - x for _, x, y in pairs]
                by_instance: dict[str, list[float]] = {}
                for (inst, x, y) in pairs:
                    by_instance.setdefault(inst, []).append(y - x)
                bases, _ = values_by_instance(report.table, base, metric)
                others, _ = values_by_instance(report.table, cell, metric)
                family.append(Comparison(
                    metric, group, report.baseline, name, len(d),
                    sum(d) / len(d) if d else math.nan,
                    stats.bootstrap_mean(list(by_instance.values()), o.seed, o.resamples),
                    stats.wilcoxon_p(d) if d else None, None,
                    stats.a12([x for g in bases.values() for x in g],
                              [x for g in others.values() for x in g]),
                    stats.improvement(d, better) if better and d else None, better,
                    len(d) > 1 and all(x == d[0] for x in d)))
        tested = [c for c in family if c.p is not None]
        for c, adjusted in zip(tested, stats.holm([c.p for c in tested])):
            c.p_holm = adjusted
        out += family
    return out


def profile_data(report: Report, metric: str) -> tuple[dict[str, list[float]],
                                                        dict[str, list[float]] | None]:
    """Performance ratios per variant over the problems — each (group, instance), its value the
    mean over that instance's runs — against the best variant, and against the reference column
    (metrics.reference_X for metrics.X) when the results have one. Empty without a better
    direction or a second architecture."""
    better = report.better.get(metric)
    if better is None or report.axis is None:  # profiles compare architectures, not cells
        return {}, None
    groups = _groups(report)
    names = sorted({name for variants in groups.values() for name in variants})
    table = report.table
    ref_col = REFERENCE + metric.removeprefix("metrics.")
    has_ref = metric.startswith("metrics.") and ref_col in table.columns
    values: dict[str, list[float | None]] = {name: [] for name in names}
    refs: list[float | None] = []
    for variants in groups.values():
        for inst in sorted({report.instance(r) for c in variants.values() for r in c.ok}):
            found = []
            for name in names:
                runs = [r for r in (variants[name].ok if name in variants else [])
                        if report.instance(r) == inst]
                xs = [x for r in runs for x in [table.number(r, metric)] if x is not None]
                values[name].append(sum(xs) / len(xs) if xs else None)
                if has_ref:
                    found += [x for r in runs for x in [table.number(r, ref_col)] if x is not None]
            refs.append(found[0] if found else None)
    ratios = stats.profile_ratios(values, better)
    if not has_ref:
        return ratios, None
    return ratios, {name: [stats.ratio(x, ref, better) for x, ref in zip(values[name], refs)]
                    for name in names}
