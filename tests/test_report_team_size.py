"""The team-size plot's data (supervisor/report_plots.team_size_series): a panel per failure
model and tasks-per-robot ratio, a line per architecture, each point a cell's mean — checked
against the rows' own means computed here — with its bootstrap interval around it."""

from __future__ import annotations

import itertools

import numpy as np

from mrta_supervisor.experiment.report import Options, build
from mrta_supervisor.experiment.report_plots import plot_team_size, team_size_series
from mrta_supervisor.experiment.results import read_results
from tests.test_report import write

ARCHS = ("cbba", "central", "murdoch")
FAILURES = ("none", "crash:role")


def value(arch: str, n: int, m: int, fail: str, seed: int) -> float:
    return 10.0 * n + m + ARCHS.index(arch) + (5.0 if fail != "none" else 0.0) + seed / 4


def rows() -> list[dict]:
    out = []
    for arch, n, per, fail, seed in itertools.product(ARCHS, (3, 5), (1, 2), FAILURES,
                                                      (1, 2, 3)):
        out.append({"run": len(out), "seed": seed, "mission": "delivery",
                    "architecture": arch, "instance": f"i{n}x{per}", "n_robots": n,
                    "n_tasks": n * per, "failure": fail, "status": "ok",
                    "metrics.makespan": value(arch, n, n * per, fail, seed)})
    return out


def test_one_panel_per_failure_and_ratio_one_line_per_architecture(tmp_path):
    folder = write(tmp_path / "r", rows())
    report = build(read_results(folder / "results.csv"),
                   Options(metrics=("metrics.makespan",), resamples=500))
    series = team_size_series(report, "metrics.makespan")
    ratio = {"M = N": 1, "M = 2N": 2}
    assert sorted(series) == sorted((f, r) for f in FAILURES for r in ratio)
    for (fail, tasks), lines in series.items():
        per = ratio[tasks]
        assert sorted(lines) == list(ARCHS)
        for arch, points in lines.items():
            assert [p.x for p in points] == [3.0, 5.0]
            for p in points:
                n = int(p.x)
                expected = np.mean([value(arch, n, n * per, fail, s) for s in (1, 2, 3)])
                assert abs(p.mean - expected) < 1e-9
                assert p.low is not None and p.low <= p.mean <= p.high
    path = plot_team_size(report, "metrics.makespan", tmp_path / "team.png")
    assert path.stat().st_size > 5_000


def test_one_ratio_makes_one_panel_per_failure(tmp_path):
    data = [r for r in rows() if r["n_tasks"] == r["n_robots"]]
    folder = write(tmp_path / "r", data)
    report = build(read_results(folder / "results.csv"),
                   Options(metrics=("metrics.makespan",), resamples=500))
    assert sorted(team_size_series(report, "metrics.makespan")) == sorted(
        (f, "") for f in FAILURES)


def test_equal_lines_are_drawn_side_by_side_not_one_over_the_other(tmp_path, monkeypatch):
    """Every architecture completing the same (5 of 5) drew one point: the last line hid the
    others (issue 51, the newcomer's list). Each line sits beside the team size, in order."""
    from mrta_supervisor.experiment import report_plots
    data = [{**r, "metrics.makespan": 5.0} for r in rows()
            if r["n_tasks"] == r["n_robots"] and r["failure"] == "none"]
    folder = write(tmp_path / "r", data)
    report = build(read_results(folder / "results.csv"),
                   Options(metrics=("metrics.makespan",), resamples=200))
    drawn = {}

    def capture(fig, path):
        ax = next(a for a in fig.axes if a.get_visible())
        drawn.update({line.get_label(): list(line.get_xdata()) for line in ax.lines})
        drawn["ticks"] = list(ax.get_xticks())
        return path

    monkeypatch.setattr(report_plots, "save_figure", capture)
    plot_team_size(report, "metrics.makespan", tmp_path / "team.png")
    xs = [drawn[a] for a in ARCHS]
    assert xs[0][0] < xs[1][0] < xs[2][0] and xs[0][1] < xs[1][1] < xs[2][1]
    assert all(abs(x - n) < 0.5 for line in xs for x, n in zip(line, (3, 5)))
    assert drawn["ticks"] == [3.0, 5.0]
