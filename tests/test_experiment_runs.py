"""`mrta experiment` end to end with the missions replaced by a stand-in that writes a summary
at once (no process): the progress total known from the start, pictures once per cell or
none, and --until-ci's blocks of seeds — deterministic, capped by --max-runs, checked against
intervals scipy computes directly."""

from __future__ import annotations

import csv
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from mrta_zenoh.cli.main import cli
from mrta_supervisor.experiment import api as experiment
from mrta_supervisor.experiment.stats import SEED
from mrta_supervisor.mission.summary import (Coverage, FailureReport, MessageRates, Summary,
                                     write_summary)


def takeover(seed: int) -> float:
    """A run's takeover: alternating 3.0 / 3.4 s, so its interval narrows as seeds are added."""
    return 3.0 if seed % 2 else 3.4


class Ended:
    returncode = 0
    stdout: list[str] = []

    def running(self) -> bool:
        return False

    def wait(self, timeout: float) -> int:
        return 0


@pytest.fixture
def missions(monkeypatch):
    """Every run's mission replaced: records (run index, seed, plots) and writes its summary."""
    started: list[tuple[int, int, bool]] = []

    def start_run(group, package, duration, run, out, plots=True, warm=False):
        started.append((run.index, run.seed, plots))
        crash = run.failure != "none"
        write_summary(out / "summary.json", Summary(
            mission="patrol", application="patrol", architecture="alliance", duration=duration,
            speed=0.0, seed=run.seed, wall_seconds=1.0, robots=["robot1", "robot2"],
            who_did_what={}, first_full_allocation=0.6,
            coverage={"wander": Coverage(0.9, 0.1, 0.0)},
            messages=MessageRates(100.0, 4.0, "alliance", total=1000), output=str(out),
            files=[], lockstep_exact=True,
            failure=FailureReport("robot2", 5.0, task="wander", taken_over_by="robot1",
                                  takeover_seconds=takeover(run.seed)) if crash else None))
        return Ended()

    monkeypatch.setattr(experiment, "start_run", start_run)
    return started


def exp_file(tmp_path: Path, seeds: str = "[1, 2]") -> Path:
    f = tmp_path / "exp.yaml"
    f.write_text(f"application: patrol\nduration: 10\nseeds: {seeds}\n"
                 "failures: [none, robot2@5]\n")
    return f


def rows(folder: Path) -> list[dict]:
    return list(csv.DictReader((folder / "results.csv").open()))


def test_the_total_is_known_before_the_first_run_ends(tmp_path, missions):
    told = []
    experiment.run_experiment(file=exp_file(tmp_path), output=tmp_path / "o", jobs=1,
                              plots=False, progress=lambda d, t, r: told.append((d, t, r)))
    assert told[0] == (0, 4, None)  # before any run: 0 of 4, not 0 of ?
    assert [(d, t) for d, t, r in told if r is not None] == [(1, 4), (2, 4), (3, 4), (4, 4)]


def test_the_bar_shows_the_total_from_the_start(monkeypatch):
    import io

    from rich.console import Console

    from mrta_supervisor.experiment import cli as experiment_cli
    out = io.StringIO()
    monkeypatch.setattr(experiment_cli, "console",
                        lambda stderr=False: Console(file=out, force_terminal=True, width=80))
    with experiment_cli.progress_reporter() as progress:
        progress(0, 12, None)
    assert "0/12" in out.getvalue() and "0/?" not in out.getvalue()


@pytest.mark.slow
def test_pictures_are_drawn_by_the_first_run_of_each_cell_and_none_with_no_plots(
        tmp_path, missions):
    experiment.run_experiment(file=exp_file(tmp_path, "[1, 2, 3]"), output=tmp_path / "o",
                              jobs=1)
    assert [p for _, _, p in sorted(missions)] == [True, False, False, True, False, False]
    assert (tmp_path / "o" / "takeover.png").is_file()
    missions.clear()
    experiment.run_experiment(file=exp_file(tmp_path, "[1, 2, 3]"), output=tmp_path / "n",
                              jobs=1, plots=False)
    assert not any(p for _, _, p in missions)
    assert not list((tmp_path / "n").glob("*.png"))
    assert (tmp_path / "n" / "summary.md").is_file() and (tmp_path / "n" / "cells.csv").is_file()


def test_a_run_without_plots_asks_the_mission_for_none():
    from mrta_supervisor.experiment.file import Run
    from mrta_supervisor.experiment.runs import demo_args

    run = Run(0, 1, "none", ())
    assert "--no-plots" in demo_args("patrol", 10.0, run, Path("o"), plots=False)
    assert "--no-plots" not in demo_args("patrol", 10.0, run, Path("o"))


def test_an_experiments_run_records_the_bus_alone_and_a_demo_what_a_viewer_draws():
    """An experiment's run records with `mrta record` (the bus: all its analysis reads), a demo
    with `mrta view` (and the channels a viewer draws), a demo served to Foxglove with the view
    whatever it asked; the bus-only recorder drains as the view does
    (test_recording_sim_time)."""
    from mrta_supervisor.experiment.file import Run
    from mrta_supervisor.experiment.runs import demo_args
    from mrta_supervisor.mission.hook import MissionOptions
    from mrta_supervisor.mission.runner import recorder_args

    args = demo_args("patrol", 10.0, Run(0, 1, "none", ()), Path("o"), plots=False)
    assert args[args.index("--recording") + 1] == "bus"
    bus = recorder_args(MissionOptions(recording="bus", output=Path("o")), "patrol", [])
    assert bus[:2] == ["record", "--sim-time"] and Path("o/run.mcap") in bus
    assert recorder_args(MissionOptions(output=Path("o")), "patrol", [])[:2] == ["view", "patrol"]
    served = MissionOptions(recording="bus", foxglove_port=8800, output=Path("o"))
    assert recorder_args(served, "patrol", [])[-2:] == ["--port", "8800"]


def bca_half_width(n: int) -> float:
    """The interval --until-ci targets, computed here with scipy directly: seeds 1…n."""
    import scipy.stats  # here, not at collection (≈ 2 CPU-s in each xdist worker)
    x = np.array([takeover(s) for s in range(1, n + 1)])
    ci = scipy.stats.bootstrap((x,), np.mean, n_resamples=10_000, method="BCa",
                               random_state=np.random.default_rng(SEED)).confidence_interval
    return (ci.high - ci.low) / 2


@pytest.mark.slow
def test_until_ci_adds_blocks_of_seeds_to_every_cell_until_the_interval_is_narrow(
        tmp_path, missions):
    target = 0.12
    # how many seeds the crash cell needs, by scipy directly (2 to start, blocks of 2)
    need = next(n for n in range(2, 40, 2) if bca_half_width(n) < target)
    assert need > 2  # the file's seeds alone are not enough
    out = tmp_path / "o"
    experiment.run_experiment(file=exp_file(tmp_path), output=out, jobs=2, plots=False,
                              until={"takeover_seconds": target}, block=2)
    got = rows(out)
    for failure in ("none", "robot2@5"):  # every cell got every block: still paired by seed
        assert sorted(int(r["seed"]) for r in got if r["failure"] == failure) == \
            list(range(1, need + 1))
    assert sorted(int(r["run"]) for r in got) == list(range(len(got)))
    md = (out / "summary.md").read_text()
    assert "## Precision\n" in md and f"{need // 2} blocks" in md
    # the same command gives the same rows
    experiment.run_experiment(file=exp_file(tmp_path), output=tmp_path / "again", jobs=1,
                              plots=False, until={"takeover_seconds": target}, block=2)
    strip = [{k: v for k, v in r.items() if k != "wall_seconds"} for r in got]
    assert strip == [{k: v for k, v in r.items() if k != "wall_seconds"}
                     for r in rows(tmp_path / "again")]


def test_until_ci_stops_at_max_runs_and_says_which_cells_missed(tmp_path, missions):
    out = tmp_path / "o"
    experiment.run_experiment(file=exp_file(tmp_path), output=out, jobs=1, plots=False,
                              until={"takeover_seconds": 0.001}, max_runs=9)
    assert len(rows(out)) == 8  # 4, then blocks of 2 (one seed × 2 cells); a fifth block: 10
    md = (out / "summary.md").read_text()
    assert "## Precision not reached" in md and "| fail=robot2@5 | `takeover_seconds` |" in md
    assert "| fail=none |" not in md.split("## Precision not reached")[1]  # no takeover there


@pytest.mark.parametrize("args,says", [
    (["--until-ci", "takeover_seconds"], "expected METRIC:HALF_WIDTH"),
    (["--until-ci", "takeover_seconds:-1"], "expected METRIC:HALF_WIDTH"),
    (["--until-ci", "takeover:0.1"], "'takeover' is not a measured column (did you mean "
                                     "'takeover_seconds'?)"),
    (["--block", "0"], "--block"),
])
def test_until_ci_usage_errors_exit_2_before_any_run(tmp_path, missions, args, says):
    result = CliRunner().invoke(cli, ["experiment", str(exp_file(tmp_path)), "--output",
                                      str(tmp_path / "o"), *args])
    assert result.exit_code == 2 and says in result.output, result.output
    assert missions == []


@pytest.mark.parametrize("name,column", [
    ("makespan", "metrics.makespan"), ("metrics.makespan", "metrics.makespan"),
    ("takeover (s)", "takeover_seconds"), ("wander covered", "wander.exactly_one"),
    ("coordination msgs/s", "coordination_messages_per_second"),
])
def test_until_ci_takes_a_metric_by_the_name_the_tables_print(name, column):
    assert experiment.parse_target(f"{name}:0.5") == (column, 0.5)


def test_the_report_takes_metrics_by_the_names_the_tables_print(tmp_path, missions):
    experiment.run_experiment(file=exp_file(tmp_path), output=tmp_path / "o", jobs=1,
                              plots=False)
    result = CliRunner().invoke(cli, ["experiment", "report", str(tmp_path / "o"), "--no-plots",
                                      "--metrics", "takeover (s),wander covered"])
    assert result.exit_code == 0, result.output
    cells = list(csv.DictReader((tmp_path / "o" / "cells.csv").open()))
    assert {c["metric"] for c in cells} == {"takeover_seconds", "wander.exactly_one"}


@pytest.mark.parametrize("target,says", [
    ("metrics.makespan:0.1", "--until-ci metrics.makespan: the patrol mission measures no "
                             "'makespan'; its metrics: border_visited, collisions_total"),
    ("metrics.colisions_total:1", "measures no 'colisions_total' (did you mean 'collisions_total'?)"),
    ("wandr covered:0.1", "the application has no task 'wandr' (did you mean 'wander'?)"),
])
@pytest.mark.parametrize("dry", [False, True])
def test_a_metric_the_runs_do_not_measure_is_refused_before_any_run(tmp_path, missions, target,
                                                                    says, dry):
    """Not after the file's whole matrix ran (the first block's report found no column), and
    by --dry-run too: a study's typo costs one line, not a night."""
    result = CliRunner().invoke(cli, ["experiment", str(exp_file(tmp_path)), "--output",
                                      str(tmp_path / "o"), "--no-plots", "--until-ci", target]
                                + (["--dry-run"] if dry else []))
    assert result.exit_code == 2 and says in result.output, result.output
    assert len(result.output.strip().splitlines()) == 1, result.output
    assert missions == [] and not (tmp_path / "o").exists()


def test_a_metric_the_runs_measure_passes_the_dry_run(tmp_path, missions):
    result = CliRunner().invoke(cli, ["experiment", str(exp_file(tmp_path)), "--output",
                                      str(tmp_path / "o"), "--dry-run", "--until-ci",
                                      "wander covered:0.1", "--until-ci", "collisions_total:1"])
    assert result.exit_code == 0 and "checked, nothing run or written" in result.output, \
        result.output


@pytest.mark.parametrize("args", [
    ["run", "{file}", "--untl-ci", "x"],        # a mistyped option
    ["{file}", "--jobs", "0"],                  # a value out of range
    ["{file}", "--until-ci", "makespan:x"],      # a value its callback refuses
    ["run"],                                    # a missing argument
    ["report"],
    ["report", "{out}", "--bogus"],
])
def test_every_usage_error_of_the_experiment_verbs_is_one_line_and_exit_2(tmp_path, missions,
                                                                          args):
    (tmp_path / "o").mkdir()
    args = [a.format(file=exp_file(tmp_path), out=tmp_path / "o") for a in args]
    result = CliRunner().invoke(cli, ["experiment", *args])
    assert result.exit_code == 2, result.output
    lines = result.output.strip().splitlines()
    assert len(lines) == 1 and " experiment " in lines[0] and lines[0].startswith("Error: "), result.output
    assert missions == []


@pytest.mark.slow
def test_every_row_names_the_parameters_of_its_cell(tmp_path, missions):
    """Under another architecture the application is still the file's (patrol, not the package
    patrol_murdoch): runs of one application under two architectures pair as one instance."""
    f = tmp_path / "exp.yaml"
    f.write_text("application: patrol\narchitecture: murdoch\nduration: 10\nseeds: [4]\n"
                 "overrides:\n  robot*.lease_timeout: [2.0, 3.0]\n")
    experiment.run_experiment(file=f, output=tmp_path / "o", jobs=1, plots=False)
    got = rows(tmp_path / "o")
    assert [(r["mission"], r["application"], r["architecture"], r["duration"], r["failure"],
             r["robot*.lease_timeout"], r["seed"]) for r in got] == [
        ("patrol", "patrol", "murdoch", "10.0", "none", "2.0", "4"),
        ("patrol", "patrol", "murdoch", "10.0", "none", "3.0", "4")]


def test_a_stop_before_any_run_ends_is_interrupted_not_an_error(tmp_path, missions):
    import threading

    from mrta_zenoh.errors import Interrupted

    stop = threading.Event()
    stop.set()
    with pytest.raises(Interrupted, match="stopped after 0 of 4 runs"):
        experiment.run_experiment(file=exp_file(tmp_path), output=tmp_path / "o", jobs=1,
                                  stop=stop, until={"takeover_seconds": 0.1})
    assert missions == []


def test_the_backends_share_the_run_helpers_without_an_import_circle():
    """The Dask backend imports the run helpers, not the module that imports it."""
    import ast

    from tests.harness.helpers import ROOT

    def imports(name: str) -> set[str]:
        tree = ast.parse((ROOT / "supervisor" / "experiment" / f"{name}.py").read_text())
        return {node.module for node in ast.walk(tree)
                if isinstance(node, ast.ImportFrom) and node.level == 1 and node.module}

    assert "api" not in imports("dask_backend")
    assert "api" not in imports("runs") | imports("file")
    assert {"file", "runs"} <= imports("dask_backend")


@pytest.mark.slow
@pytest.mark.multiprocess
@pytest.mark.timeout(240)
def test_a_demo_without_plots_draws_no_picture_and_measures_the_same(children, tmp_path):
    import json

    out = {}
    for plots in (True, False):
        out[plots] = tmp_path / str(plots)
        demo = children.mrta("-q", "demo", "--duration", "8", "--speed", "0", "--seed", "3",
                             "--fail", "none", "--no-live", "--output", out[plots],
                             *([] if plots else ["--no-plots"]), name=f"demo {plots}")
        assert demo.wait(200) == 0, demo.tail(20)
    assert not list(out[False].glob("*.png")) and (out[False] / "run.mcap").stat().st_size
    assert {"world.png", "timeline.png"} <= {p.name for p in out[True].glob("*.png")}
    drawn, bare = (json.loads((out[p] / "summary.json").read_text()) for p in (True, False))
    for s in (drawn, bare):
        s.pop("wall_seconds"), s.pop("output"), s.pop("files")
    assert drawn == bare  # the pictures change nothing measured
