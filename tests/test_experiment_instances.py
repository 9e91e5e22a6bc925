"""`mrta experiment` over instances and architectures, with the missions replaced by a stand-in
that writes a summary at once (no process): the matrix (sizes crossed, tasks per robot, counts,
names, numbering), the instances made once into the output folder — each the file `mrta
instance generate` writes for its size and seed — the rows' columns, and bad blocks refused at
their line before anything runs."""

from __future__ import annotations

import csv
from pathlib import Path

import pytest
from click.testing import CliRunner

from mrta_zenoh.cli.main import cli
from mrta_supervisor.experiment import api as experiment
from mrta_supervisor.experiment.file import load_experiment
from mrta_supervisor.mission.summary import (Coverage, FailureReport, MessageRates, Summary,
                                     write_summary)


class Ended:
    returncode = 0
    stdout: list[str] = []

    def running(self) -> bool:
        return False

    def wait(self, timeout: float) -> int:
        return 0


@pytest.fixture
def missions(monkeypatch):
    """Every run's mission replaced: records what it was started with, writes a summary whose
    robots are its instance's and whose coverage names its instance's tasks."""
    started: list[dict] = []

    def start_run(group, package, duration, run, out, plots=True, instance=None, warm=False):
        inst = instance or (run.instance.path if run.instance is not None else None)
        started.append({"index": run.index, "package": package.name, "seed": run.seed,
                        "failure": run.failure, "instance": inst, "plots": plots})
        robots = list(run.instance.robots) if run.instance is not None else ["robot1"]
        fault = run.failure.split(":")[-1].split("@")[0] if run.failure != "none" else None
        write_summary(out / "summary.json", Summary(
            mission="delivery", application=package.name, architecture="x", duration=duration,
            speed=0.0, seed=run.seed, wall_seconds=1.0, robots=robots, who_did_what={},
            first_full_allocation=0.5, coverage={"t1": Coverage(0.9, 0.1, 0.0)},
            messages=MessageRates(100.0, 4.0, "alliance", total=1000), output=str(out),
            files=[], lockstep_exact=True, metrics={"makespan": 10.0 + run.seed},
            failure=FailureReport(fault, 5.0) if fault else None))
        return Ended()

    monkeypatch.setattr(experiment, "start_run", start_run)
    return started


def write(tmp_path: Path, text: str) -> Path:
    f = tmp_path / "exp.yaml"
    f.write_text(text)
    return f


def rows(folder: Path) -> list[dict]:
    return list(csv.DictReader((folder / "results.csv").open()))


BLOCK = ("application: delivery\nduration: 10\nseeds: [1, 2]\n"
         "architectures: [alliance, murdoch]\n"
         "instances:\n  generator: delivery\n  robots: [2, 3]\n  tasks: [1, 4]\n  count: 2\n"
         "  seed: 5\n")


def test_sizes_are_crossed_counted_and_numbered_cell_by_cell(tmp_path, missions):
    f = write(tmp_path, BLOCK)
    exp = load_experiment(f)
    # 2 architectures × (2 robots × 2 tasks sizes × 2 instances) × 1 failure × 2 seeds
    assert exp.count() == 2 * 8 * 2 == 32
    got = experiment.run_experiment(file=f, output=tmp_path / "o", jobs=2, plots=False)
    assert len(got) == 32 and [r["run"] for r in got] == list(range(32))
    # numbering: architecture, then size, then instance, then seed (seed innermost)
    expected = [(a, r, t, seed, s) for a in ("alliance", "murdoch") for r in (2, 3)
                for t in (1, 4) for seed in (5, 6) for s in (1, 2)]
    assert [(r["architecture"], r["n_robots"], r["n_tasks"], r["instance"], r["seed"])
            for r in got] == [(a, r, t, f"delivery-r{r}-t{t}-{seed}", s)
                              for a, r, t, seed, s in expected]
    assert got[0]["config"] == "arch=alliance robots=2 tasks=1 fail=none"
    assert {m["package"] for m in missions} == {"delivery", "delivery_murdoch"}
    # every run got its instance's file, in the output folder
    for m, row in zip(sorted(missions, key=lambda m: m["index"]), got):
        assert m["instance"] == (tmp_path / "o" / "instances" / f"{row['instance']}.yaml"
                                 ).resolve()


@pytest.mark.parametrize("sizes,expected", [
    ("  robots: [2, 4]\n  tasks_per_robot: [1, 1.5]\n", [(2, 2), (2, 3), (4, 4), (4, 6)]),
    ("  robots: [3, 1]\n", [(3, 3), (1, 1)]),  # neither: tasks = robots
    ("  robots: [2]\n  tasks_per_robot: [1.25]\n", [(2, 3)]),  # 2.5 → 3 (halves up)
])
def test_tasks_per_robot_and_the_default_of_one_task_per_robot(tmp_path, missions, sizes,
                                                                 expected):
    f = write(tmp_path, "application: delivery\nduration: 10\nseeds: [1]\ninstances:\n"
                        "  generator: delivery\n" + sizes)
    got = experiment.run_experiment(file=f, output=tmp_path / "o", jobs=1, plots=False)
    assert [(int(r["n_robots"]), int(r["n_tasks"])) for r in got] == expected


def test_each_instance_is_the_file_instance_generate_writes_for_its_size_and_seed(tmp_path,
                                                                                 missions):
    f = write(tmp_path, "application: delivery\nduration: 10\nseeds: [1]\ninstances:\n"
                        "  generator: delivery\n  parameters: {walls: 1, rate: 0.2}\n"
                        "  robots: [3]\n  tasks: [4]\n  count: 2\n  seed: 40\n")
    out = tmp_path / "o"
    experiment.run_experiment(file=f, output=out, jobs=1, plots=False)
    made = sorted((out / "instances").iterdir())
    assert [p.name for p in made] == ["delivery-r3-t4-w1-40.yaml", "delivery-r3-t4-w1-41.yaml"]
    for seed, path in zip((40, 41), made):  # the verb, run here as a user would
        by_hand = tmp_path / f"hand{seed}.yaml"
        result = CliRunner().invoke(cli, ["instance", "generate", "delivery", "--robots", "3",
                                          "--tasks", "4", "--walls", "1", "--rate", "0.2",
                                          "--seed", str(seed), "-o", str(by_hand)])
        assert result.exit_code == 0, result.output
        assert path.read_bytes() == by_hand.read_bytes()
    # made again, the same bytes
    again = tmp_path / "again"
    experiment.run_experiment(file=f, output=again, jobs=1, plots=False)
    assert [p.read_bytes() for p in made] == \
        [p.read_bytes() for p in sorted((again / "instances").iterdir())]


def test_instance_files_are_named_by_their_names_and_runs_are_paired_by_instance(tmp_path,
                                                                                missions):
    folder = tmp_path / "mine"
    folder.mkdir()
    for seed, stem in ((1, "b"), (2, "a")):
        CliRunner().invoke(cli, ["instance", "generate", "delivery", "--robots", "2",
                                 "--tasks", "2", "--seed", str(seed), "-o",
                                 str(folder / f"{stem}.yaml")])
    text = (folder / "a.yaml").read_text()
    (folder / "c.yaml").write_text(text.replace("name: delivery-r2-t2-2\n", ""))  # no name
    f = write(tmp_path, "application: delivery\nduration: 10\nseeds: [3]\n"
                        "failures: [none, robot2@4]\ninstances:\n  files: [\"mine/*.yaml\"]\n")
    got = experiment.run_experiment(file=f, output=tmp_path / "o", jobs=1, plots=False)
    # sorted files; a document's own name, else its stem: never a path
    assert [r["instance"] for r in got] == ["delivery-r2-t2-2", "delivery-r2-t2-1", "c"] * 2
    assert sorted(p.name for p in (tmp_path / "o" / "instances").iterdir()) == [
        "c.yaml", "delivery-r2-t2-1.yaml", "delivery-r2-t2-2.yaml"]
    assert [r["failed_robot"] for r in got] == [""] * 3 + ["robot2"] * 3


def test_rows_carry_the_instance_and_no_coverage_per_task(tmp_path, missions):
    out = tmp_path / "o"
    experiment.run_experiment(file=write(tmp_path, BLOCK), output=out, jobs=1, plots=False)
    header = next(csv.reader((out / "results.csv").open()))
    assert header[:11] == ["run", "config", "seed", "mission", "application", "duration",
                           "architecture", "instance", "n_robots", "n_tasks", "failure"]
    assert not [c for c in header if c.startswith("t1.")]  # task ids are per instance
    assert "metrics.makespan" in header
    md = (out / "summary.md").read_text()
    assert "8 instances (`instance` column)" in md
    # cells: architecture × size; compared across architectures within each size
    cells = list(csv.DictReader((out / "cells.csv").open()))
    assert len({(c["architecture"], c["n_robots"], c["n_tasks"]) for c in cells}) == 8
    pairs = [c for c in csv.DictReader((out / "comparisons.csv").open())
             if c["metric"] == "metrics.makespan"]
    assert len(pairs) == 4 and all(c["pairs"] == "4" for c in pairs)  # 2 instances × 2 seeds


@pytest.mark.parametrize("block,where,what", [
    ("instances:\n  generator: delivery\n  robotz: [2]\n", ":6", "unknown key 'robotz' (did "
                                                                "you mean 'robots'?)"),
    ("instances:\n  generator: delivry\n  robots: [2]\n", ":5", "no instance generator "
                                                              "'delivry' (did you mean "
                                                              "'delivery'?)"),
    ("instances:\n  generator: delivery\n  robots: [2]\n  parameters: {wals: 1}\n", ":7",
     "unknown parameter 'wals' of generator 'delivery' (did you mean 'walls'?)"),
    ("instances:\n  generator: delivery\n  robots: [2]\n  parameters: {walls: -1}\n", ":7",
     "walls"),
    ("instances:\n  generator: delivery\n  robots: [2]\n  parameters: {robots: 3}\n", ":7",
     "robots is the block's own list"),
    ("instances:\n  generator: delivery\n  robots: [2, 0]\n", ":6", "robots[1]"),
    ("instances:\n  generator: delivery\n  robots: [2]\n  tasks: [1]\n"
     "  tasks_per_robot: [1]\n", ":8", "give tasks: or tasks_per_robot:, not both"),
    ("instances:\n  generator: delivery\n  robots: [2]\n  count: 0\n", ":7", "count:"),
    ("instances:\n  generator: delivery\n", ":4", "a generator needs robots:"),
    ("instances:\n  files: [nothing/*.yaml]\n", ":5", "matches no file"),
    ("instances:\n  files: [x.yaml]\n  count: 2\n", ":6", "count is for a generator"),
    ("instances: [x]\n", ":4", "instances must be a mapping"),
    ("architectures: [alliance, mudroch]\n", ":4", "'mudroch'"),
    ("architectures: [alliance, alliance]\n", ":4", "'alliance' is listed twice"),
    ("architecture: murdoch\narchitectures: [alliance]\n", ":5", "not both"),
    ("instances:\n  generator: delivery\n  robots: [2, 5]\nfailures: [robot4@3]\n", ":7",
     "robot4 is not one of the application's robots (robot1, robot2) (did you mean "
     "'robot2'?) (instance delivery-r2-t2-0)"),
    ("instances:\n  generator: delivery\n  robots: [2]\n"
     "overrides:\n  robit*.spin_rate: [5]\n", ":8", "no parameter file of package 'delivery' "
                                                 "matches 'robit*'"),
    ("instances:\n  generator: delivery\n  robots: [2]\nrobots: [2]\n", ":7",
     "the team sizes are the instances block's"),
])
def test_bad_blocks_exit_2_naming_file_line_and_key(tmp_path, missions, block, where, what):
    f = write(tmp_path, "application: delivery\nduration: 10\nseeds: [1]\n" + block)
    result = CliRunner().invoke(cli, ["experiment", str(f), "--output", str(tmp_path / "o")])
    assert result.exit_code == 2, result.output
    line = result.output.strip().splitlines()[-1]
    assert f"exp.yaml{where}" in line and what in line, line
    assert missions == [] and not (tmp_path / "o" / "results.csv").exists()


def test_an_application_without_instances_refuses_the_block(tmp_path, missions):
    f = write(tmp_path, "application: patrol\nduration: 10\nseeds: [1]\ninstances:\n"
                        "  generator: delivery\n  robots: [2]\n")
    result = CliRunner().invoke(cli, ["experiment", str(f), "--output", str(tmp_path / "o")])
    assert result.exit_code == 2 and "exp.yaml:4" in result.output, result.output
    assert "the 'patrol' mission reads no instance files" in result.output


def test_a_matrix_too_large_names_its_instances_and_architectures(tmp_path, missions):
    f = write(tmp_path, "application: delivery\nduration: 10\nseeds: [1, 2]\n"
                        "architectures: [alliance, murdoch]\ninstances:\n  generator: delivery\n"
                        "  robots: [2, 3, 4]\n  count: 10\n")
    result = CliRunner().invoke(cli, ["experiment", str(f), "--output", str(tmp_path / "o"),
                                      "--max-runs", "100"])
    assert result.exit_code == 2, result.output
    assert ("makes 120 runs (30 instances × 2 architectures × 1 failure × 1 override "
            "combinations × 2 seeds)") in result.output
    assert not (tmp_path / "o").exists()  # refused before any instance is made


def test_a_dispatcher_crash_is_a_fault_of_central_and_refused_elsewhere(tmp_path, missions):
    block = ("duration: 10\nseeds: [1]\nfailures: [none, \"crash:dispatcher@5\"]\n"
             "instances:\n  generator: delivery\n  robots: [2]\n")
    f = write(tmp_path, "application: delivery\narchitecture: central\n" + block)
    got = experiment.run_experiment(file=f, output=tmp_path / "o", jobs=1, plots=False)
    assert [r["failure"] for r in got] == ["none", "crash:dispatcher@5"]
    f = write(tmp_path, "application: delivery\narchitecture: alliance\n" + block)
    result = CliRunner().invoke(cli, ["experiment", str(f), "--output", str(tmp_path / "p")])
    assert result.exit_code == 2 and "dispatcher is not one of" in result.output, result.output


@pytest.mark.slow
def test_until_ci_adds_instances_when_the_file_has_a_generator_and_scalars_read_as_lists(
        tmp_path, missions, monkeypatch):
    """`seeds: 2`, `robots: 2` read as [1, 2] and [2]; `makespan` is metrics.makespan; the
    blocks add instances (the generator's next seeds after the file's), never seeds: the
    makespan here varies by instance alone, which more seeds could not narrow."""
    from mrta_supervisor.mission.summary import read_summary

    inner = experiment.start_run

    def start_run(group, package, duration, run, out, plots=True, instance=None, warm=False):
        child = inner(group, package, duration, run, out, plots, instance)
        summary = read_summary(out / "summary.json")
        summary.metrics = {"makespan": 10.0 + int(run.instance.name.rsplit("-", 1)[1]) % 3}
        write_summary(out / "summary.json", summary)
        return child
    monkeypatch.setattr(experiment, "start_run", start_run)
    f = write(tmp_path, "application: delivery\nduration: 10\nseeds: 2\ninstances:\n"
                        "  generator: delivery\n  robots: 2\n  count: 2\n  seed: 5\n")
    out = tmp_path / "o"
    experiment.run_experiment(file=f, output=out, jobs=1, plots=False, max_runs=10,
                              until={experiment.parse_target("makespan:0.01")[0]: 0.01})
    got = rows(out)
    assert {r["seed"] for r in got} == {"1", "2"}  # no seed added
    names = list(dict.fromkeys(r["instance"] for r in got))
    assert names == [f"delivery-r2-t2-{s}" for s in range(5, 10)]  # 2, then one a block
    assert len(got) == 10 and (out / "instances" / "delivery-r2-t2-9.yaml").is_file()
    md = (out / "summary.md").read_text()
    assert "each after the file's own: 1 new instance of every size" in md, md


def test_a_dry_run_checks_the_file_and_its_instances_and_writes_nothing(tmp_path):
    """`mrta experiment run FILE --dry-run`: the matrix said, every instance made and read back
    (a room too small for the team is refused as a run would refuse it), nothing written."""
    f = tmp_path / "e.yaml"
    f.write_text("application: delivery\narchitectures: [central]\nduration: 30\nseeds: [1]\n"
                 "instances: {generator: delivery, robots: 3, tasks: 4, count: 2, seed: 2}\n")
    out = tmp_path / "o"
    result = CliRunner().invoke(cli, ["experiment", "run", str(f), "--output", str(out),
                                      "--dry-run"])
    assert result.exit_code == 0, result.output
    assert "2 runs — 1 cell × 2 instances (3 robots × 4 tasks) × 1 seed; 0 already" \
        in result.output
    assert not out.exists()
    f.write_text(f.read_text().replace("seed: 2}", "seed: 2, parameters: {room: [2, 2]}}"))
    result = CliRunner().invoke(cli, ["experiment", "run", str(f), "--output", str(out),
                                      "--dry-run"])
    assert result.exit_code == 2 and "could not place" in result.output
    assert not out.exists()
