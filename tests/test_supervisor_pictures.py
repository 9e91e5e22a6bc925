"""Pictures a user reads beside the summary: nothing in them hides what they
show."""

from __future__ import annotations

import csv
import pytest

from mrta_supervisor.experiment import report, report_plots
from mrta_supervisor.experiment.results import read_results


@pytest.mark.slow
def test_the_coverage_legend_hides_no_bar(tmp_path, monkeypatch):
    """Patrol's wander is covered ≈ 99 % of a run: its bar reaches the top, so a legend
    inside the axes would hide it."""
    figures = {}
    save = report_plots.save_figure

    def keep(fig, output):
        fig.canvas.draw()
        renderer = fig.canvas.get_renderer()
        ax = fig.axes[0]
        figures[output.name] = ([p.get_window_extent(renderer) for p in ax.patches],
                                [lg.get_window_extent(renderer)
                                 for lg in [ax.get_legend(), *fig.legends] if lg is not None])
        return save(fig, output)

    monkeypatch.setattr(report_plots, "save_figure", keep)
    rows = [{"failure": c, "seed": str(seed), "status": "ok", "takeover_seconds": "3.6",
             "wander.exactly_one": 0.99, "border_protection.exactly_one": 0.91,
             "report.exactly_one": 0.2} for c in ("none", "robot2@30")
            for seed in (1, 2)]
    path = tmp_path / "results.csv"
    with path.open("w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)
    report_plots.plot_coverage(report.build(read_results(path)), tmp_path / "coverage.png")
    bars, legends = figures["coverage.png"]
    assert len(bars) == 6 and legends
    for legend in legends:
        assert not any(legend.overlaps(bar) for bar in bars)
