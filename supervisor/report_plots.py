"""The report's pictures, from the same figures as its tables (report.py):

* `takeover.png` — the takeover time of every run, per cell (box plots);
* `coverage.png` — per cell and task, the share of the run with exactly one robot on it (mean
  and its bootstrap interval);
* `profile_<metric>.png` — Dolan and Moré's performance profile of each compared variant
  (architecture, or cell) for each metric with a known better direction, beside its profile
  against the reference value when results.csv has one;
* `team_size_<metric>.png` — each metric against the team size (`n_robots` column, when the
  results have one), mean with its bootstrap band.
"""

from __future__ import annotations

import math
from pathlib import Path

from mrta_zenoh.files import save_figure

from . import stats
from .report import Report, profile_data
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
    if "takeover_seconds" in report.table.columns:
        written.append(plot_takeover(report, output / "takeover.png"))
    if any(c.endswith(".exactly_one") for c in report.table.columns):
        written.append(plot_coverage(report, output / "coverage.png"))
    for m in report.metrics:
        ratios, against_ref = profile_data(report, m)
        if ratios:
            written.append(plot_profile(m, ratios, against_ref, output / f"profile_{m}.png"))
        if TEAM in report.table.parameters:
            written.append(plot_team_size(report, m, output / f"team_size_{m}.png"))
    return written


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


def plot_team_size(report: Report, metric: str, path: Path) -> Path:
    plt = _pyplot()
    lines: dict[str, dict[float, object]] = {}
    for cell in report.cells:
        size = cell.value(TEAM)
        try:
            x = float(size)
        except ValueError:
            continue
        label = " ".join(f"{k}={v}" for k, v in cell.key if k not in (TEAM, "n_tasks")
                         and len({c.value(k) for c in report.cells}) > 1) or "all"
        lines.setdefault(label, {})[x] = report.figure(cell, metric)
    fig, ax = plt.subplots(figsize=(6, 4), dpi=100)
    try:
        for label, points in sorted(lines.items()):
            xs = sorted(x for x, f in points.items() if f.n)
            ax.plot(xs, [points[x].mean for x in xs], marker="o", label=label)
            band = [x for x in xs if points[x].interval is not None]
            ax.fill_between(band, [points[x].interval.low for x in band],
                            [points[x].interval.high for x in band], alpha=0.2)
        ax.set_xlabel("team size (robots)")
        ax.set_ylabel(title(metric))
        ax.legend(fontsize=7)
        fig.tight_layout()
        return save_figure(fig, path)
    finally:
        plt.close(fig)
