"""An experiment's runs in agent hosts: the file's `agents_per_process:` (10 unless it says),
`mrta experiment run --agents-per-process K` over it, each run's `mrta demo` asked for it, and
results.csv saying which — as bookkeeping, not a parameter: hosts change no result, so the cells
are the same whatever K."""

import csv
import json
from pathlib import Path

import pytest
from click.testing import CliRunner

from mrta_supervisor.experiment.file import load_experiment
from mrta_supervisor.experiment.file import AGENTS_PER_PROCESS
from mrta_supervisor.experiment.runs import demo_args
from mrta_supervisor.experiment.results import kind
from mrta_zenoh.cli.main import cli


def _file(tmp_path: Path, extra: str = "") -> Path:
    f = tmp_path / "exp.yaml"
    f.write_text("application: delivery\nduration: 10\nseeds: [1, 2]\n" + extra)
    return f


def test_runs_use_hosts_by_default_and_the_file_may_ask_for_a_process_per_robot(tmp_path):
    runs = load_experiment(_file(tmp_path)).runs()
    assert {r.agents_per_process for r in runs} == {AGENTS_PER_PROCESS} and AGENTS_PER_PROCESS > 1
    args = demo_args("delivery", 10.0, runs[0], Path("o"))
    assert args[args.index("--agents-per-process") + 1] == str(AGENTS_PER_PROCESS)
    one = load_experiment(_file(tmp_path, "agents_per_process: 1\n")).runs()
    assert {r.agents_per_process for r in one} == {1}


@pytest.mark.parametrize("value, what", [("0", "at least 1"), ("two", "agents_per_process")])
def test_a_bad_agents_per_process_is_refused_at_its_line(tmp_path, value, what):
    f = _file(tmp_path, f"agents_per_process: {value}\n")
    result = CliRunner().invoke(cli, ["experiment", str(f), "--output", str(tmp_path / "o")])
    assert result.exit_code == 2, result.output
    line = result.output.strip().splitlines()[-1]
    assert "exp.yaml:4" in line and what in line, line


def test_the_command_line_replaces_the_files_value(tmp_path, monkeypatch):
    from mrta_supervisor.experiment import api as experiment
    seen = []

    def stop_before_running(exp, output, shard=None, until=None):
        seen.append([r.agents_per_process for r in exp.runs()])
        raise experiment.ConfigError("stopped here")
    monkeypatch.setattr(experiment, "prepare_experiment", stop_before_running)
    f = _file(tmp_path, "agents_per_process: 4\n")
    result = CliRunner().invoke(cli, ["experiment", "run", str(f), "--output",
                                      str(tmp_path / "o"), "--agents-per-process", "1"])
    assert result.exit_code == 2 and seen == [[1, 1]], result.output
    result = CliRunner().invoke(cli, ["experiment", "run", str(f), "--output",
                                      str(tmp_path / "o")])
    assert seen[-1] == [4, 4]


def test_the_column_is_bookkeeping_not_a_cell_parameter():
    assert kind("agents_per_process") == "bookkeeping"


@pytest.mark.multiprocess
@pytest.mark.slow
@pytest.mark.timeout(600)
def test_an_experiment_in_hosts_gives_the_rows_of_one_process_per_robot(children, tmp_path):
    rows = {}
    for k in (1, 5):
        out = tmp_path / f"k{k}"
        run = children.mrta("experiment", "run", _file(tmp_path, "failures: [robot3@5]\n"),
                            "--output", out, "--agents-per-process", str(k), "--no-plots",
                            name=f"experiment-k{k}")
        assert run.wait(500) == 0, run.stderr[-10:]
        rows[k] = list(csv.DictReader((out / "results.csv").open()))
    assert [r["agents_per_process"] for r in rows[5]] == ["5", "5"]
    machine = {"wall_seconds", "agents_per_process", "decision_ms_median", "decision_ms_max",
               "messages", "messages_per_second", "namespace_messages_per_second"}
    for one, hosted in zip(rows[1], rows[5]):
        assert {k: v for k, v in one.items() if k not in machine} == \
            {k: v for k, v in hosted.items() if k not in machine}
    assert json.loads((tmp_path / "k5" / "run000" / "summary.json").read_text())["lockstep_exact"]
