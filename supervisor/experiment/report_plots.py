"""The report's pictures, from the same figures as its tables (report.py):

* `takeover.png` — the takeover time of every run, per cell (box plots);
* `coverage.png` — per cell and task, the share of the run with exactly one robot on it (mean
  and its bootstrap interval);
* `profile_<metric>.png` — Dolan and Moré's performance profile of each compared variant
  (architecture, or cell) for each metric with a known better direction, beside its profile
  against the reference value when results.csv has one;
* `team_size_<metric>.png` — each metric against the team size (`n_robots` column, when the
  results have one): a panel per failure model (and tasks-per-robot ratio), a line per
  architecture, mean with its bootstrap band (`team_size_series`).
"""

from __future__ import annotations

import hashlib
import math
import re
from dataclasses import dataclass
from pathlib import Path

from mrta_zenoh.files import save_figure

from . import stats
from .report import ARCHITECTURE, Report, profile_data
from .report_md import title

TEAM = "n_robots"


def _pyplot():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def plot_report(report: Report, output: Path) -> list[Path]:
    """Every picture the report has data for; returns the files written."""
    written = []
    # issue 51, the newcomer's list: an empty takeover.png when no fault ran, and pictures of
    # columns with one value throughout (nothing to compare) — neither is drawn
    if varied(report, "takeover_seconds", at_least=1):
        written.append(plot_takeover(report, output / "takeover.png"))
    if any(c.endswith(".exactly_one") for c in report.table.columns):
        written.append(plot_coverage(report, output / "coverage.png"))
    for m in report.metrics:
        if not varied(report, m):
            continue
        ratios, against_ref = profile_data(report, m)
        if ratios:
            written.append(plot_profile(m, ratios, against_ref,
                                        output / f"profile_{file_part(m)}.png"))
        if TEAM in report.table.parameters:
            written.append(plot_team_size(report, m, output / f"team_size_{file_part(m)}.png"))
    for stale in PICTURES:  # an earlier report's (other --metrics): not beside the new ones
        for path in output.glob(stale):
            if path not in written:
                path.unlink()
    return written


def varied(report: Report, column: str, at_least: int = 2) -> bool:
    """Whether the column has at least `at_least` distinct values over the runs that ended
    well (2: there is something to compare; 1: there is anything at all)."""
    if column not in report.table.columns:
        return False
    values = {report.table.number(r, column) for c in report.cells for r in c.ok} - {None}
    return len(values) >= at_least


PICTURES = ("takeover.png", "coverage.png", "profile_*.png", "team_size_*.png")


def file_part(column: str) -> str:
    """A column's name as part of a file name (issue 51.5: a column `metrics.../../x` named a
    file outside the folder): letters, digits, `.`, `_` and `-` kept, anything else `_`, no
    leading dot, at most 80 characters; a name changed so gains 8 hex digits of its hash, so
    two columns never share a file."""
    part = re.sub(r"[^A-Za-z0-9._-]", "_", column).lstrip(".")[:80]
    if part == column:
        return part
    return f"{part}-{hashlib.blake2s(column.encode(), digest_size=4).hexdigest()}"


def plot_takeover(report: Report, path: Path) -> Path:
    plt = _pyplot()
    data = [[x for r in c.ok for x in [report.table.number(r, "takeover_seconds")]
             if x is not None] for c in report.cells]
    fig, ax = plt.subplots(figsize=(max(6, 1.6 * len(report.cells)), 4), dpi=100)
    try:
        shown = [(c.label, d) for c, d in zip(report.cells, data) if d]
        if shown:
            ax.boxplot([d for _, d in shown])
            ax.set_xticks(range(1, len(shown) + 1), [label for label, _ in shown])
        ax.set_ylabel("takeover time (s)")
        ax.set_title("takeover after a failure, per cell")
        ax.tick_params(axis="x", labelsize=7, rotation=15)
        fig.tight_layout()
        return save_figure(fig, path)
    finally:
        plt.close(fig)


def plot_coverage(report: Report, path: Path) -> Path:
    plt = _pyplot()
    tasks = [c.removesuffix(".exactly_one") for c in report.table.columns
             if c.endswith(".exactly_one")]
    cells = report.cells
    fig, ax = plt.subplots(figsize=(max(6, 1.6 * len(cells)), 4), dpi=100)
    try:
        width = 0.8 / max(1, len(tasks))
        for i, t in enumerate(tasks):
            figures = [_figures(report, c, f"{t}.exactly_one") for c in cells]
            means = [0.0 if f.n == 0 else f.mean for f in figures]
            low = [0.0 if f.interval is None else f.mean - f.interval.low for f in figures]
            high = [0.0 if f.interval is None else f.interval.high - f.mean for f in figures]
            ax.bar([j + i * width for j in range(len(cells))], means, width, label=t,
                   yerr=[low, high], capsize=3)
        ax.set_xticks([j + width * (len(tasks) - 1) / 2 for j in range(len(cells))])
        ax.set_xticklabels([c.label for c in cells], fontsize=7, rotation=15)
        ax.set_ylabel("share with exactly one robot")
        ax.set_ylim(0, 1.05)
        # beside the axes: inside, "best" still sat on a bar near 1 (patrol's wander)
        ax.legend(fontsize=8, loc="upper left", bbox_to_anchor=(1.0, 1.0))
        fig.tight_layout()
        return save_figure(fig, path)
    finally:
        plt.close(fig)


def _figures(report: Report, cell, metric: str) -> stats.Describe:
    if metric in report.metrics:
        return report.figure(cell, metric)
    from .report import values_by_instance

    groups, missing = values_by_instance(report.table, cell, metric)
    return stats.describe(list(groups.values()), missing, report.options.seed,
                          report.options.resamples)


def _taus(ratios: dict[str, list[float]]) -> list[float]:
    finite = [r for rs in ratios.values() for r in rs if math.isfinite(r)]
    top = max(finite + [1.0]) * 1.05 + 1e-9
    return sorted({1.0, top, *finite})


def plot_profile(metric: str, ratios: dict[str, list[float]],
                 against_ref: dict[str, list[float]] | None, path: Path) -> Path:
    plt = _pyplot()
    panels = [("best variant", ratios)] + ([("reference", against_ref)] if against_ref else [])
    fig, axes = plt.subplots(1, len(panels), figsize=(5.5 * len(panels), 4), dpi=100,
                             squeeze=False)
    try:
        for ax, (against, data) in zip(axes[0], panels):
            taus = _taus(data)
            for variant, rs in data.items():
                ax.step(taus, stats.profile(rs, taus), where="post", label=variant)
            ax.set_xlabel(f"τ (within a factor τ of the {against})")
            ax.set_ylabel("share of problems")
            ax.set_ylim(-0.02, 1.02)
            ax.set_title(f"{title(metric)}: performance profile against the {against}",
                         fontsize=9)
            ax.legend(fontsize=8)
        fig.tight_layout()
        return save_figure(fig, path)
    finally:
        plt.close(fig)


@dataclass(frozen=True)
class Point:
    """One cell's figure at one team size: its mean and bootstrap interval (None: none)."""

    x: float
    mean: float
    low: float | None
    high: float | None


def team_size_series(report: Report, metric: str) -> dict[tuple[str, str], dict[str, list[Point]]]:
    """What `team_size_<metric>.png` draws: (failure, tasks per robot) → line label → points
    in team-size order. One panel per failure model, and per tasks-per-robot ratio
    (`n_tasks` / `n_robots`, "M = 2N"; "" when the cells have only one) — a metric against N
    means little with M = N and M = 2N mixed on one line; one line per architecture (with any
    other parameter that varies); each point a cell's mean with its bootstrap interval. Cells
    with no value, or no numeric team size, are left out."""
    def varies(k: str) -> bool:
        return len({c.value(k) for c in report.cells}) > 1

    ratios = {_ratio(c) for c in report.cells} - {None}
    panels: dict[tuple, dict[str, list[Point]]] = {}
    for cell in report.cells:
        try:
            x = float(cell.value(TEAM))
        except ValueError:
            continue
        f = report.figure(cell, metric)
        if not f.n:
            continue
        ratio = _ratio(cell) if len(ratios) > 1 else None
        panel = (cell.value("failure"), -1.0 if ratio is None else ratio)
        label = " ".join(f"{k}={v}" for k, v in cell.key
                         if k not in (TEAM, "n_tasks", "failure") and varies(k)) or "all"
        if label.startswith(f"{ARCHITECTURE}="):
            label = label.removeprefix(f"{ARCHITECTURE}=")
        low, high = (None, None) if f.interval is None else (f.interval.low, f.interval.high)
        panels.setdefault(panel, {}).setdefault(label, []).append(Point(x, f.mean, low, high))
    out: dict[tuple[str, str], dict[str, list[Point]]] = {}
    for (failure, ratio), lines in sorted(panels.items()):
        tasks = "" if ratio < 0 else "M = N" if ratio == 1 else f"M = {ratio:g}N"
        out[(failure, tasks)] = {label: sorted(points, key=lambda p: p.x)
                                 for label, points in sorted(lines.items())}
    return out


def _ratio(cell) -> float | None:
    try:
        return round(float(cell.value("n_tasks")) / float(cell.value(TEAM)), 3)
    except (ValueError, ZeroDivisionError):
        return None


def dodge(k: int, n: int, sizes: list[float]) -> float:
    """How far line `k` of `n` is drawn beside the team sizes `sizes`: spread over a fifth of
    the smallest gap between two sizes (of one, if there is one size)."""
    gap = min((b - a for a, b in zip(sizes, sizes[1:])), default=1.0)
    return 0.0 if n < 2 else (k - (n - 1) / 2) * 0.2 * gap / (n - 1)


def plot_team_size(report: Report, metric: str, path: Path) -> Path:
    plt = _pyplot()
    series = team_size_series(report, metric)
    labels = sorted({label for lines in series.values() for label in lines})
    colours = {label: f"C{k % 10}" for k, label in enumerate(labels)}
    # a row per failure model, a column per tasks-per-robot ratio
    failures = list(dict.fromkeys(f for f, _ in series)) or [""]
    ratios = list(dict.fromkeys(r for _, r in series)) or [""]
    fig, axes = plt.subplots(len(failures), len(ratios),
                             figsize=(4.2 * len(ratios) + 1.8, 3.2 * len(failures)), dpi=100,
                             squeeze=False, sharey=True)
    try:
        for ax in axes.flat:
            ax.set_visible(False)
        for (failure, ratio), lines in series.items():
            ax = axes[failures.index(failure), ratios.index(ratio)]
            ax.set_visible(True)
            name = ", ".join(x for x in (f"fail={failure}" if failure else "", ratio) if x)
            sizes = sorted({p.x for points in lines.values() for p in points})
            for label, points in lines.items():
                # each line a little to the side of the team size it is at: equal lines (every
                # architecture completing 5 of 5) hid each other, showing only the last drawn
                # (issue 51, the newcomer's list); the ticks stay at the team sizes
                dx = dodge(labels.index(label), len(labels), sizes)
                xs = [p.x + dx for p in points]
                ax.plot(xs, [p.mean for p in points], marker="o", color=colours[label],
                        label=label)
                band = [(x, p) for x, p in zip(xs, points) if p.low is not None]
                ax.errorbar([x for x, _ in band], [p.mean for _, p in band],
                            yerr=[[p.mean - p.low for _, p in band],
                                  [p.high - p.mean for _, p in band]],
                            fmt="none", ecolor=colours[label], alpha=0.6, capsize=2)
            ax.set_title(name or "all runs", fontsize=9)
            ax.set_xlabel("team size (robots)")
            ax.set_xticks(sorted({p.x for points in lines.values() for p in points}))
        for ax in axes[:, 0]:
            ax.set_ylabel(title(metric))
        # one legend for every panel, beside them: inside a panel it covered the data
        handles = [plt.Line2D([], [], color=colours[label], marker="o", label=label)
                   for label in labels]
        fig.legend(handles=handles, fontsize=8, loc="upper left",
                   bbox_to_anchor=(1.0 - 1.7 / fig.get_figwidth(), 0.95))
        fig.suptitle(f"{title(metric)} against team size (mean, 95 % bootstrap interval;"
                     " lines side by side)",
                     fontsize=10)
        fig.tight_layout(rect=(0.0, 0.0, 1.0 - 1.8 / fig.get_figwidth(), 1.0))
        return save_figure(fig, path)
    finally:
        plt.close(fig)
