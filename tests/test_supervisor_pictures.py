"""Pictures a user reads beside the summary (issue 37 point 12): nothing in them hides what they
show."""

from __future__ import annotations

from mrta_supervisor import experiment


def test_the_coverage_legend_hides_no_bar(tmp_path, monkeypatch):
    """Patrol's wander is covered ≈ 99 % of a run: its bar reaches the top, where the legend
    used to sit."""
    from mrta_zenoh import files

    figures = {}
    save = files.save_figure

    def keep(fig, output):
        fig.canvas.draw()
        renderer = fig.canvas.get_renderer()
        ax = fig.axes[0]
        figures[output.name] = ([p.get_window_extent(renderer) for p in ax.patches],
                                [lg.get_window_extent(renderer)
                                 for lg in [ax.get_legend(), *fig.legends] if lg is not None])
        return save(fig, output)

    monkeypatch.setattr(files, "save_figure", keep)
    rows = [{"config": c, "status": "ok", "takeover_seconds": "3.6",
             "wander.exactly_one": 0.99, "border_protection.exactly_one": 0.91,
             "report.exactly_one": 0.2} for c in ("fail=none", "fail=robot2@30") for _ in (1, 2)]
    experiment.plot_results(rows, tmp_path)
    bars, legends = figures["coverage.png"]
    assert len(bars) == 6 and legends
    for legend in legends:
        assert not any(legend.overlaps(bar) for bar in bars)
