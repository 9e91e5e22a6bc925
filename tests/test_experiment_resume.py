"""Resuming `mrta experiment` (supervisor/experiment/resume.py) with the missions replaced by the stand-in
of tests/test_experiment_runs.py: an interrupted folder resumed runs exactly the missing runs
and ends with an uninterrupted run's rows; results.csv alone is enough; a torn last line is
run again; a folder of another file, or of another matrix's rows, is refused with nothing
written. (The same across processes, a run killed by PID: test_experiment_resume_multiprocess.)"""

from __future__ import annotations

import csv
import threading
from pathlib import Path

import pytest
from click.testing import CliRunner

from mrta_zenoh.cli.main import cli
from mrta_zenoh.errors import Interrupted
from mrta_supervisor.experiment import api as experiment
from mrta_supervisor.experiment import resume as experiment_resume
from mrta_supervisor.experiment.results import MACHINE_TIME
from tests.test_experiment_runs import exp_file, missions, rows  # noqa: F401 (a fixture)


SEEDS = "[1, 2, 3]"  # × failures [none, robot2@5]: 6 runs


def same(table: list[dict]) -> list[dict]:
    return [{k: v for k, v in r.items() if k not in MACHINE_TIME} for r in table]


def interrupted(tmp_path: Path, after: int, seeds: str = SEEDS) -> Path:
    """An experiment stopped (as by Ctrl-C) once `after` runs have ended."""
    stop = threading.Event()

    def progress(done, total, row):
        if done >= after:
            stop.set()
    out = tmp_path / "resumed"
    with pytest.raises(Interrupted, match="the same command resumes"):
        experiment.run_experiment(file=exp_file(tmp_path, seeds), output=out, jobs=1,
                                  plots=False, stop=stop, progress=progress)
    return out


def uninterrupted(tmp_path: Path, seeds: str = SEEDS) -> list[dict]:
    experiment.run_experiment(file=exp_file(tmp_path, seeds), output=tmp_path / "whole",
                              jobs=1, plots=False)
    return rows(tmp_path / "whole")


def test_a_resumed_folder_runs_only_the_missing_runs_and_ends_with_the_uninterrupted_rows(
        tmp_path, missions):
    whole = uninterrupted(tmp_path)
    missions.clear()
    out = interrupted(tmp_path, after=2)
    assert len(rows(out)) == 2 and (out / "experiment.json").is_file()
    first = {i for i, _, _ in missions}
    missions.clear()
    got = experiment.run_experiment(file=exp_file(tmp_path, SEEDS), output=out, jobs=1, plots=False)
    again = [i for i, _, _ in missions]
    assert sorted(again) == sorted(set(range(6)) - first)  # the missing runs, each once
    assert len(got) == 6
    assert [r["run"] for r in rows(out)] == [str(i) for i in range(6)]  # none twice
    assert same(rows(out)) == same(whole)
    # and a finished folder resumed runs nothing
    missions.clear()
    experiment.run_experiment(file=exp_file(tmp_path, SEEDS), output=out, jobs=1, plots=False)
    assert missions == [] and same(rows(out)) == same(whole)


def test_results_csv_alone_resumes_and_a_torn_last_line_runs_again(tmp_path, missions):
    whole = uninterrupted(tmp_path)
    out = interrupted(tmp_path, after=3)
    for folder in out.glob("run*"):  # the run folders are optional
        for f in folder.iterdir():
            f.unlink()
        folder.rmdir()
    (out / "experiment.json").unlink()  # and so is the identity: rows are checked instead
    csv_text = (out / "results.csv").read_text()
    torn = csv_text[:-7]  # the last row cut off mid-line, as a copy made mid-write leaves it
    (out / "results.csv").write_text(torn)
    kept = {r["run"] for r in rows(out)[:-1]}
    missions.clear()
    experiment.run_experiment(file=exp_file(tmp_path, SEEDS), output=out, jobs=1, plots=False)
    assert {str(i) for i, _, _ in missions} == {str(i) for i in range(6)} - kept
    assert same(rows(out)) == same(whole)
    assert (out / "experiment.json").is_file()


def test_a_folder_stopped_before_its_first_row_resumes_every_run(tmp_path, missions):
    """Stopped before any run ended (a study's next file, Ctrl-C'd at its start): no
    results.csv is left, and a blank one (what such a stop once left, the header of no
    column) resumes as no row instead of being refused as a table without a header."""
    whole = uninterrupted(tmp_path)
    out = interrupted(tmp_path, after=0)
    assert not (out / "results.csv").exists()
    (out / "results.csv").write_bytes(b"\r\n")
    missions.clear()
    experiment.run_experiment(file=exp_file(tmp_path, SEEDS), output=out, jobs=1, plots=False)
    assert sorted(i for i, _, _ in missions) == list(range(6))
    assert same(rows(out)) == same(whole)


def listing(folder: Path) -> dict[str, tuple[int, int]]:
    return {str(p.relative_to(folder)): (p.stat().st_size, p.stat().st_mtime_ns)
            for p in sorted(folder.rglob("*"))}


def test_another_file_into_the_folder_is_refused_with_one_line_and_nothing_written(
        tmp_path, missions):
    out = interrupted(tmp_path, after=1)
    before = listing(out)
    other = tmp_path / "other.yaml"
    other.write_text("application: patrol\nduration: 10\nseeds: [1, 2, 4]\n"
                     "failures: [none, robot2@5]\n")
    missions.clear()
    res = CliRunner().invoke(cli, ["experiment", str(other), "--output", str(out)])
    assert res.exit_code == 2, res.output
    lines = [line for line in res.output.splitlines() if line.strip()]
    assert len(lines) == 1 and "another experiment" in lines[0] and "exp.yaml" in lines[0]
    assert "Traceback" not in res.output
    assert missions == [] and listing(out) == before
    # the same content under another name (another machine's checkout) is the same file
    moved = tmp_path / "moved" / "exp.yaml"
    moved.parent.mkdir()
    moved.write_text(exp_file(tmp_path, SEEDS).read_text() + "# a comment changes nothing\n")
    experiment.run_experiment(file=moved, output=out, jobs=1, plots=False)
    assert len(rows(out)) == 6


def test_rows_of_another_matrix_without_an_identity_are_refused_naming_their_line(
        tmp_path, missions):
    out = interrupted(tmp_path, after=2)
    (out / "experiment.json").unlink()
    table = rows(out)
    table[1]["seed"] = "9"  # the second row (line 3): another seed than its run's
    with (out / "results.csv").open("w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(table[0]))
        w.writeheader()
        w.writerows(table)
    before = listing(out)
    res = CliRunner().invoke(cli, ["experiment", str(exp_file(tmp_path, SEEDS)), "--output", str(out)])
    assert res.exit_code == 2, res.output
    assert "results.csv:3" in res.output and "seed '9'" in res.output, res.output
    assert listing(out) == before


@pytest.mark.slow
def test_until_ci_resumed_runs_only_the_blocks_rows_it_lacks(tmp_path, missions):
    f = exp_file(tmp_path, "[1, 2]")
    experiment.run_experiment(file=f, output=tmp_path / "whole", jobs=1, plots=False,
                              until={"takeover_seconds": 0.001}, max_runs=9)
    whole = rows(tmp_path / "whole")
    assert len(whole) == 8  # two blocks were added (tests/test_experiment_runs.py)
    stop = threading.Event()
    out = tmp_path / "resumed"

    def progress(done, total, row):
        if done >= 5:  # within the first block
            stop.set()
    with pytest.raises(Interrupted):
        experiment.run_experiment(file=f, output=out, jobs=1, plots=False, stop=stop,
                                  progress=progress, until={"takeover_seconds": 0.001},
                                  max_runs=9)
    missions.clear()
    experiment.run_experiment(file=f, output=out, jobs=1, plots=False,
                              until={"takeover_seconds": 0.001}, max_runs=9)
    assert len(missions) == len(whole) - 5
    assert same(rows(out)) == same(whole)


# ------------------------------------------------------------------ shards
def shard(tmp_path: Path, which: str, name: str | None = None) -> Path:
    out = tmp_path / (name or f"shard{which.replace('/', 'of')}")
    experiment.run_experiment(file=exp_file(tmp_path, SEEDS), output=out, jobs=1, plots=False,
                              shard=experiment_resume.parse_shard(which))
    return out


def report(*args) -> object:
    return CliRunner().invoke(cli, ["experiment", "report", *map(str, args), "--no-plots"])


def test_two_shards_reported_together_equal_the_unsharded_study(tmp_path, missions):
    whole = uninterrupted(tmp_path)
    missions.clear()
    a = shard(tmp_path, "1/2")
    assert sorted(i for i, _, _ in missions) == [0, 2, 4]  # every 2nd run from the 1st
    missions.clear()
    b = shard(tmp_path, "2/2")
    assert sorted(i for i, _, _ in missions) == [1, 3, 5]
    res = report(a, b, "--output", tmp_path / "merged")
    assert res.exit_code == 0, res.output
    merged = tmp_path / "merged"
    assert same(rows(merged)) == same(whole)
    for name in ("cells.csv", "comparisons.csv"):
        assert (merged / name).read_text() == (tmp_path / "whole" / name).read_text(), name
    # the merged folder is the whole matrix's: resuming it runs nothing
    missions.clear()
    experiment.run_experiment(file=exp_file(tmp_path, SEEDS), output=merged, jobs=1,
                              plots=False)
    assert missions == []


def test_folders_reported_together_refuse_a_run_twice_and_another_file(tmp_path, missions):
    a = shard(tmp_path, "1/2")
    copy = shard(tmp_path, "1/2", name="again")
    res = report(a, copy, "--output", tmp_path / "m")
    assert res.exit_code == 2 and "run 0 (seed 1, fail=none)" in res.output, res.output
    assert "again/results.csv:2" in res.output and len(res.output.strip().splitlines()) == 1
    other = tmp_path / "other.yaml"
    other.write_text(exp_file(tmp_path, "[1, 2]").read_text())
    experiment.run_experiment(file=other, output=tmp_path / "o", jobs=1, plots=False)
    res = report(a, tmp_path / "o", "--output", tmp_path / "m")
    assert res.exit_code == 2 and "different experiments" in res.output, res.output
    res = report(a, copy)
    assert res.exit_code == 2 and "--output" in res.output
    assert len(res.output.strip().splitlines()) == 1 and not (tmp_path / "m").exists()


@pytest.mark.parametrize("args,says", [
    (["--shard", "3/2"], "expected I/N"),
    (["--shard", "0/2"], "expected I/N"),
    (["--shard", "1/2", "--until-ci", "takeover_seconds:0.1"], "every row of the matrix"),
])
def test_shard_usage_errors_exit_2_before_any_run(tmp_path, missions, args, says):
    res = CliRunner().invoke(cli, ["experiment", str(exp_file(tmp_path, SEEDS)), "--output",
                                   str(tmp_path / "o"), *args])
    assert res.exit_code == 2 and says in res.output, res.output
    assert missions == [] and not (tmp_path / "o").exists()


def test_a_shards_folder_resumes_that_shard_only(tmp_path, missions):
    a = shard(tmp_path, "1/2")
    res = CliRunner().invoke(cli, ["experiment", str(exp_file(tmp_path, SEEDS)), "--output",
                                   str(a), "--shard", "2/2"])
    assert res.exit_code == 2 and "shard 1/2" in res.output, res.output
    res = CliRunner().invoke(cli, ["experiment", str(exp_file(tmp_path, SEEDS)), "--output",
                                   str(a)])
    assert res.exit_code == 2 and "shard 1/2" in res.output and "every run" in res.output
