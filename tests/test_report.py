"""`mrta experiment report DIR`: the report rebuilt from results.csv alone — its figures against
independent computations (numpy, scipy called directly, the definitions), the words it uses
for degenerate and ragged data, and bad input as exit 2 naming the file, line and column."""

from __future__ import annotations

import csv
import itertools
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from mrta_zenoh.cli.main import cli
from mrta_supervisor.experiment.stats import SEED
from tests.test_stats import holm_by_definition

TAKEOVER = {"alliance": [3.1, 2.9, 3.4, 3.0, 3.8, 2.7], "murdoch": [2.3, 2.4, 2.3, 2.2, 2.9, 2.3]}
MAKESPAN = {"alliance": [25.0, None, 27.5, 24.0, 26.0, 25.5],    # seed 2: a task never served
            "murdoch": [23.0, 22.5, None, None, 23.5, 24.0]}


def rows() -> list[dict]:
    out = []
    for arch in ("alliance", "murdoch"):
        for fail in ("none", "robot2@20"):
            for i, seed in enumerate(range(1, 7)):
                out.append({
                    "run": len(out), "config": f"fail={fail}", "seed": seed, "mission": "delivery",
                    "application": "delivery", "architecture": arch, "duration": 40.0,
                    "failure": fail, "status": "ok", "error": "", "wall_seconds": 1.0,
                    "takeover_seconds": "" if fail == "none" else TAKEOVER[arch][i],
                    "t1.exactly_one": 0.25, "metrics.makespan": MAKESPAN[arch][i] or "",
                    "metrics.completed": 4 if MAKESPAN[arch][i] else 3})
    out[-1]["status"], out[-1]["error"] = "failed", "exit 1: Error: the simulator died"
    return out


def write(folder: Path, data: list[dict]) -> Path:
    folder.mkdir(parents=True, exist_ok=True)
    fields = list(dict.fromkeys(k for r in data for k in r))
    with (folder / "results.csv").open("w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=fields)
        w.writeheader()
        w.writerows(data)
    return folder


def report(folder: Path, *args: str):
    return CliRunner().invoke(cli, ["experiment", "report", str(folder), *args])


def table(path: Path) -> list[dict]:
    return list(csv.DictReader(path.open()))


def test_cells_csv_holds_each_cells_figures_as_numpy_and_scipy_give_them(tmp_path):
    import scipy.stats  # here, not at collection (≈ 2 CPU-s in each xdist worker)
    folder = write(tmp_path / "r", rows())
    result = report(folder, "--baseline", "murdoch", "--no-plots")
    assert result.exit_code == 0, result.output
    cells = table(folder / "cells.csv")
    take = next(c for c in cells if c["metric"] == "takeover_seconds"
                and c["architecture"] == "alliance" and c["failure"] == "robot2@20")
    x = np.array(TAKEOVER["alliance"])
    q1, med, q3 = np.quantile(x, [0.25, 0.5, 0.75])
    assert (int(take["n"]), int(take["missing"])) == (6, 0)
    assert float(take["mean"]) == x.mean() and float(take["median"]) == med
    assert float(take["iqr"]) == q3 - q1
    assert float(take["iqm"]) == scipy.stats.trim_mean(x, 0.25)
    boot = scipy.stats.bootstrap((x,), np.mean, n_resamples=10_000, method="BCa",
                                 random_state=np.random.default_rng(SEED))
    assert (float(take["boot_low"]), float(take["boot_high"])) == (
        boot.confidence_interval.low, boot.confidence_interval.high)  # full precision
    t = scipy.stats.t.ppf(0.975, 5) * x.std(ddof=1) / np.sqrt(6)
    assert float(take["t_high"]) == pytest.approx(x.mean() + t, rel=1e-12)
    assert f"seed {SEED}" in (folder / "summary.md").read_text()


def test_a_metric_missing_in_some_runs_is_counted_apart_never_averaged_as_zero(tmp_path):
    folder = write(tmp_path / "r", rows())
    assert report(folder, "--no-plots").exit_code == 0
    cells = table(folder / "cells.csv")
    mk = next(c for c in cells if c["metric"] == "metrics.makespan"
              and c["architecture"] == "murdoch" and c["failure"] == "robot2@20")
    present = [v for v in MAKESPAN["murdoch"][:5] if v is not None]  # seed 6 failed
    assert (int(mk["n"]), int(mk["missing"]), int(mk["failed"])) == (len(present), 2, 1)
    assert float(mk["mean"]) == pytest.approx(np.mean(present))
    md = (folder / "summary.md").read_text()
    assert "missing in 2 of 5" in md
    none = next(c for c in cells if c["metric"] == "takeover_seconds" and c["failure"] == "none")
    assert (none["n"], none["mean"]) == ("0", "")  # nothing failed: no takeover, not 0 s
    assert "| murdoch: fail=robot2@20 | 6 (1) |" in md
    assert "| murdoch: fail=none | 6 (0) | – (missing in 6 runs) |" in md
    assert "25.00 % (identical in every run)" in md  # t1 covered 25 % in every run: words
    assert "± 0.00" not in md


def test_comparisons_are_paired_by_seed_with_wilcoxon_holm_a12_and_improvement(tmp_path):
    import scipy.stats  # here, not at collection (≈ 2 CPU-s in each xdist worker)
    data = rows()
    # a second group of the other parameters, so a metric's Holm family has two members
    extra = [dict(r, run=100 + i, failure="stall:robot2@20", config="fail=stall:robot2@20",
                  takeover_seconds=float(r["takeover_seconds"] or 5.0) + 0.1 * i)
             for i, r in enumerate(data) if r["failure"] == "robot2@20"]
    folder = write(tmp_path / "r", data + extra)
    result = report(folder, "--baseline", "murdoch", "--metrics", "takeover_seconds",
                    "--no-plots")
    assert result.exit_code == 0, result.output
    comps = table(folder / "comparisons.csv")
    crash = next(c for c in comps if c["cell"] == "fail=robot2@20")
    # murdoch's seed 6 failed: 5 pairs, other − baseline per seed
    d = [a - b for a, b in zip(TAKEOVER["alliance"][:5], TAKEOVER["murdoch"][:5])]
    assert (crash["baseline"], crash["other"], int(crash["pairs"])) == ("murdoch", "alliance", 5)
    assert float(crash["mean_difference"]) == pytest.approx(np.mean(d))
    p = scipy.stats.wilcoxon(d, zero_method="wilcox", method="auto").pvalue
    assert float(crash["wilcoxon_p"]) == p
    a = TAKEOVER["alliance"]
    b = TAKEOVER["murdoch"][:5]
    a12 = sum((x < y) + 0.5 * (x == y) for x in b for y in a) / (len(a) * len(b))
    assert float(crash["a12"]) == pytest.approx(a12)
    assert float(crash["improvement"]) == sum(x < 0 for x in d) / len(d)  # lower is better
    tested = [c for c in comps if c["wilcoxon_p"]]
    assert len(tested) == 2  # fail=none has no takeover: no pair, out of the family
    assert [float(c["holm_p"]) for c in tested] == pytest.approx(
        holm_by_definition([float(c["wilcoxon_p"]) for c in tested]))
    md = (folder / "summary.md").read_text()
    assert "Holm family: the 2 comparisons of `takeover_seconds` with a p-value in this table " \
           "(1 without one" in md
    assert "Lower is better: A12 below 0.5 favours the other." in md


@pytest.mark.slow
def test_the_same_results_give_the_same_report(tmp_path):
    a, b = write(tmp_path / "a", rows()), write(tmp_path / "b", rows())
    for folder in (a, b):
        assert report(folder, "--no-plots").exit_code == 0
    for name in ("summary.md", "cells.csv", "comparisons.csv"):
        assert (a / name).read_bytes() == (b / name).read_bytes(), name


@pytest.mark.slow
def test_instances_make_a_two_level_bootstrap_and_team_sizes_a_plot(tmp_path):
    data = []
    for arch, inst, seed in itertools.product(("alliance", "murdoch"), ("i1", "i2", "i3"),
                                              (1, 2)):
        n = 3 if inst != "i3" else 5
        data.append({"run": len(data), "seed": seed, "architecture": arch, "instance": inst,
                     "n_robots": n, "failure": "none", "status": "ok",
                     "metrics.makespan": 20 + n + seed + (arch == "murdoch"),
                     "metrics.reference_makespan": 20 + n})
    folder = write(tmp_path / "r", data)
    result = report(folder, "--baseline", "murdoch", "--metrics", "metrics.makespan")
    assert result.exit_code == 0, result.output
    cells = table(folder / "cells.csv")
    three = next(c for c in cells if c["n_robots"] == "3" and c["architecture"] == "alliance")
    assert three["boot_method"] == "percentile, instances then seeds" and three["n"] == "4"
    # no mission column: which way is better is not known, so no profile is drawn
    assert not (folder / "profile_metrics.makespan.png").exists()
    assert (folder / "team_size_metrics.makespan.png").stat().st_size > 5_000


@pytest.mark.slow
def test_profiles_are_drawn_for_a_metric_whose_direction_the_mission_declares(tmp_path):
    folder = write(tmp_path / "r", rows())
    assert report(folder, "--metrics", "metrics.makespan").exit_code == 0
    assert (folder / "profile_metrics.makespan.png").stat().st_size > 5_000
    assert "`metrics.makespan`, lower is better" in (folder / "summary.md").read_text()


def test_one_architecture_compares_each_cell_with_the_first(tmp_path):
    data = [r for r in rows() if r["architecture"] == "alliance"]
    folder = write(tmp_path / "r", data)
    assert report(folder, "--no-plots").exit_code == 0
    md = (folder / "summary.md").read_text()
    assert "each cell against `fail=none`" in md and "fail=none → fail=robot2@20" in md


@pytest.mark.parametrize("edit,args,says", [
    (lambda d: [{k: v for k, v in r.items() if k != "status"} for r in d], [],
     "results.csv:1: 'status': missing column 'status'"),
    (lambda d: [dict(r, seed="x") if r["run"] == 3 else r for r in d], [],
     "results.csv:5: 'seed': not an integer: 'x'"),
    (lambda d: [dict(r, takeover_seconds="fast") if r["run"] == 7 else r for r in d], [],
     "results.csv:9: 'takeover_seconds': not a number: 'fast'"),
    (lambda d: d, ["--metrics", "takeover"],
     "results.csv:1: no column 'takeover' (did you mean 'takeover_seconds'?)"),
    (lambda d: d, ["--metrics", "seed"], "'seed' is a bookkeeping column, not a measured one"),
    (lambda d: d, ["--baseline", "murdock"],
     "--baseline 'murdock': not an architecture of these results (did you mean 'murdoch'?)"),
])
def test_bad_results_exit_2_naming_file_line_and_column(tmp_path, edit, args, says):
    folder = write(tmp_path / "r", edit(rows()))
    result = report(folder, "--no-plots", *args)
    assert result.exit_code == 2, result.output
    assert says in result.output.strip().splitlines()[-1], result.output
    assert "Traceback" not in result.output and not (folder / "summary.md").exists()


def test_report_usage_errors_exit_2(tmp_path):
    result = report(tmp_path / "nowhere")
    assert result.exit_code == 2 and "does not exist" in result.output
    (tmp_path / "empty").mkdir()
    result = report(tmp_path / "empty")
    assert result.exit_code == 2 and "results.csv: cannot read the results" in result.output


def test_experiment_runs_a_file_and_report_rebuilds_through_one_group(tmp_path, monkeypatch):
    """`mrta experiment FILE` (the default command) and `mrta experiment report DIR` both
    work; `--help` lists both."""
    from mrta_supervisor.experiment import cli as experiment_cli
    called = {}
    monkeypatch.setattr(experiment_cli, "run_experiment",
                        lambda **kw: called.setdefault("run", kw) and [])
    f = tmp_path / "exp.yaml"
    f.write_text("application: patrol\nduration: 10\nseeds: [1]\n")
    (tmp_path / "o").mkdir()
    (tmp_path / "o" / "summary.md").write_text("# s\n")
    result = CliRunner().invoke(cli, ["experiment", "--jobs", "2", str(f), "--output",
                                      str(tmp_path / "o")])
    assert result.exit_code == 0, result.output
    assert called["run"]["file"] == f and called["run"]["jobs"] == 2
    helped = CliRunner().invoke(cli, ["experiment", "--help"])
    assert helped.exit_code == 0 and "report" in helped.output and "FILE.yaml" in helped.output


def test_no_picture_of_nothing_an_empty_takeover_or_a_constant_column(tmp_path):
    """Issue 51, the newcomer's list: a report of runs with no fault drew an empty
    takeover.png, and columns with one value throughout were plotted (nothing to compare)."""
    data = [{**r, "failure": "none", "config": "fail=none", "takeover_seconds": "",
             "metrics.completed": 4} for r in rows() if r["failure"] == "none"]
    folder = write(tmp_path / "r", data)
    assert report(folder, "--metrics", "metrics.makespan,metrics.completed").exit_code == 0
    assert not (folder / "takeover.png").exists()
    assert not list(folder.glob("profile_metrics.completed*.png"))  # 4 in every run
    assert (folder / "profile_metrics.makespan.png").stat().st_size > 5_000


def test_the_verb_prints_the_overview_and_names_the_rest_of_summary_md(tmp_path):
    """`mrta experiment` and `report` printed the whole summary.md (≈ 600 lines for the study:
    issue 51, the newcomer's list): now its title, lead and Overview, then where the rest is."""
    folder = write(tmp_path / "r", rows())
    result = report(folder, "--baseline", "murdoch", "--no-plots")
    assert result.exit_code == 0, result.output
    whole = (folder / "summary.md").read_text()
    sections = [line[3:] for line in whole.splitlines() if line.startswith("## ")]
    assert sections[0] == "Overview" and len(sections) >= 3
    printed = result.output.rstrip()
    assert printed.startswith(whole[:whole.index("\n## ", whole.index("## Overview"))].rstrip())
    assert printed.endswith(f"In {folder / 'summary.md'} besides: {', '.join(sections[1:])}.")
    assert "## " + sections[1] not in printed and len(printed) < len(whole) / 2
