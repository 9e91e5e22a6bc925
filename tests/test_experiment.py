"""`mrta experiment`: a tiny matrix end to end, a failed run, parameter overrides, bad files."""

import csv
import time
from pathlib import Path

import pytest
from click.testing import CliRunner

from mrta_zenoh.cli.main import cli
from mrta_zenoh.errors import ConfigError
from mrta_supervisor.experiment.api import load_experiment
from mrta_supervisor.experiment.stats import mean_ci
from tests.harness.helpers import kill_descendant


@pytest.mark.multiprocess
@pytest.mark.slow
@pytest.mark.timeout(900)
def test_a_tiny_matrix_gives_one_row_per_run_and_records_a_failed_run(children, tmp_path):
    f = tmp_path / "exp.yaml"
    # every value is valid (an absurd one is refused before any run): the failed run is
    # one whose mission process this test kills
    f.write_text("application: patrol\nduration: 30\nseeds: [1, 2]\nfailures: [robot2@18]\n"
                 "overrides:\n  robot2.spin_rate: [10, 5]\n")
    out = tmp_path / "out"
    run = children.mrta("experiment", f, "--output", out, "--jobs", "2", name="experiment")
    # generous: run003 starts once two runs have ended, minutes on a loaded machine
    deadline = time.monotonic() + 600
    while kill_descendant(run.proc.pid, "demo", str(out / "run003")) is None:
        assert time.monotonic() < deadline and run.running(), run.stderr[-10:]
        time.sleep(0.05)
    # four 30-s missions at full speed, two at a time: ≈ 15 s on an idle machine; a sweep
    # with failed runs exits 1 once everything is written
    assert run.wait(600) == 1, run.stderr[-10:] + run.stdout[-10:]
    assert any("1 of 4 runs failed" in line for line in run.stderr), run.stderr[-5:]
    assert sum(line.startswith("[") for line in run.stderr) == 4  # progress, on stderr
    rows = list(csv.DictReader((out / "results.csv").open()))
    assert len(rows) == 4
    assert {(r["seed"], r["robot2.spin_rate"]) for r in rows} == {
        ("1", "10"), ("2", "10"), ("1", "5"), ("2", "5")}
    failed = [r for r in rows if r["status"] == "failed"]
    assert [r["run"] for r in failed] == ["3"] and failed[0]["error"].startswith("exit -9"), failed
    ok = [r for r in rows if r["status"] == "ok"]
    for r in ok:  # the killed robot's border protection was taken over
        assert r["taken_over_by"] in ("robot1", "robot3") and 0 < float(r["takeover_seconds"]) < 10
        assert float(r["wander.exactly_one"]) > 0.8 and int(r["messages"]) > 1000
    summary = (out / "summary.md").read_text()
    assert "fail=robot2@18" in summary and "Failed runs" in summary
    assert "collisions_total" in summary  # the application's own metrics, named by it
    for name in ("takeover.png", "coverage.png"):
        assert (out / name).stat().st_size > 5_000


def test_a_failed_runs_error_names_the_process_and_its_exit_code_even_under_a_long_tail():
    from mrta_supervisor.experiment.api import error_of
    lines = ["Error: record exited with code 1:", "[record]"] + [f"line {i}" for i in range(12)]
    cell = error_of(1, lines)
    assert cell.startswith("exit 1: Error: record exited with code 1:") and "line 11" in cell


@pytest.mark.slow
@pytest.mark.multiprocess
@pytest.mark.timeout(150)
def test_ctrl_c_keeps_exactly_the_finished_runs(children, tmp_path):
    """After a Ctrl-C, results.csv and summary.md describe the runs that finished — no more
    (the stopped ones), no less (one that ended just before) — and the exit status is 130."""
    import signal
    import time
    f = tmp_path / "exp.yaml"
    f.write_text("application: patrol\nduration: 8\nseeds: [1, 2, 3, 4, 5, 6]\n"
                 "failures: [none]\n")
    out = tmp_path / "out"
    run = children.mrta("experiment", f, "--output", out, "--jobs", "1", name="experiment")
    deadline = time.monotonic() + 100
    while not (out / "results.csv").exists() or \
            len((out / "results.csv").read_text().splitlines()) < 2:
        assert time.monotonic() < deadline and run.proc.poll() is None, run.tail()
        time.sleep(0.2)
    run.signal(signal.SIGINT)
    assert run.wait(60) == 130, run.tail(10)
    rows = list(csv.DictReader((out / "results.csv").open()))
    assert 1 <= len(rows) < 6 and all(r["status"] == "ok" for r in rows)
    seeds = ", ".join(r["seed"] for r in rows)
    assert f"over seeds ({seeds})" in (out / "summary.md").read_text()


def test_summary_pairs_configurations_by_seed_and_names_only_the_seeds_that_ran(tmp_path):
    from mrta_supervisor.experiment.report import Options
    from mrta_supervisor.experiment.report_md import write_report
    from mrta_supervisor.experiment.results import write_csv
    rows = [{"run": i, "config": f"fail={c}", "seed": seed, "failure": c, "status": "ok",
             "takeover_seconds": t, "wander.exactly_one": 0.9, "metrics.collisions_total": 0}
            for i, (c, seed, t) in enumerate([("a", 1, 3.0), ("a", 2, 4.0), ("a", 3, 5.0),
                                              ("b", 1, 3.5), ("b", 2, 4.5)])]
    write_csv(tmp_path / "results.csv", rows, [])
    report = write_report(tmp_path, options=Options(plots=False))
    md = (tmp_path / "summary.md").read_text()
    assert "over seeds (1, 2, 3)" in md  # seed 4 never ran (a Ctrl-C): not claimed
    comparison = next(c for c in report.comparisons if c.metric == "takeover_seconds")
    assert (comparison.baseline, comparison.other, comparison.pairs) == ("fail=a", "fail=b", 2)
    assert comparison.mean_difference == 0.5  # seed 3 has no pair; both differences are 0.5
    assert "| – | fail=a → fail=b | 2 | 0.500 (identical in every pair) |" in md
    assert "### collisions_total" in md


def test_overrides_make_one_configuration_per_value(tmp_path):
    f = tmp_path / "exp.yaml"
    f.write_text("application: patrol\nduration: 10\nseeds: [1, 2, 3]\nfailures: [none]\n"
                 "overrides:\n  robot*.timeout_duration: [2.0, 4.0]\n")
    runs = load_experiment(f).runs()
    assert len(runs) == 6 and len({r.config for r in runs}) == 2


def test_an_override_changes_the_files_of_that_run_only(tmp_path):
    import yaml

    from mrta_zenoh.toolchain.registry import Registry
    from mrta_supervisor.experiment.api import package_copy
    pkg, _ = Registry().application("patrol")
    copy = package_copy(pkg.path, tmp_path, (("robot*.timeout_duration", 4.5),))
    for i in (1, 2, 3):
        doc = yaml.safe_load((copy / "config" / f"robot{i}_alliance_params.yaml").read_text())
        assert doc["timeout_duration"] == 4.5
    original = yaml.safe_load((pkg.path / "config" / "robot1_alliance_params.yaml").read_text())
    assert original["timeout_duration"] != 4.5


@pytest.mark.parametrize("text,where,what", [
    ("application: patrol\nduration: 10\nseeds: [1]\nfailure: [none]\n", ":4", "did you mean 'failures'"),
    ("application: patrol\nduration: -1\nseeds: [1]\n", ":2", "between 0.001 and 604800 s"),
    # finite but absurd: the run never ended
    ("application: patrol\nduration: 1.0e+308\nseeds: [1]\n", ":2",
     "must be between 0.001 and 604800 s (a millisecond to a week), got 1e+308"),
    ("application: patrol\nduration: 10\nseeds: [1, -3]\n", ":3", "seeds[1]: must be between 0"),
    # a failure of a robot the application does not have: refused up front, or every run fails
    ("application: patrol\nduration: 10\nseeds: [1]\nfailures: [none, robot9@5]\n", ":4",
     "robot9 is not one of the application's robots (robot1, robot2, robot3)"),
    ("application: patrol\nduration: 10\nseeds: [1]\nfailures: [robot2@50]\n", ":4",
     "50 s is not before the end of the run (10 s)"),
    # a million runs: refused before anything starts, the counts named
    ("application: patrol\nduration: 10\nseeds: [1]\noverrides:\n"
     + "".join(f"  robot*.k{i}: [{', '.join(map(str, range(100)))}]\n" for i in range(3)),
     "exp.yaml", "makes 1,000,000 runs (1 failure × 1,000,000 override combinations × 1 seed)"),
    ("application: patrol\nduration: 10\nseeds: [1, x]\n", ":3", "seeds[1]"),
    ("application: patrol\nduration: 10\nseeds: [1]\nfailures: [robot2 at 5]\n", ":4",
     "ROBOT@SECONDS"),
    # refused here, not by the mission in every run: one grammar
    ("application: patrol\nduration: 10\nseeds: [1]\nfailures: [none, robot2@0]\n", ":4",
     "seconds > 0"),
    ("application: patrol\nduration: 10\n", "exp.yaml", "missing mandatory key 'seeds'"),
    ("application: patrol\nduration: 10\nseeds: [1]\noverrides: {timeout: [1]}\n", ":4",
     "FILE_GLOB.KEY.PATH"),
    # an absurd overridden value: refused at its line before any run, not by every run using it
    ("application: patrol\nduration: 10\nseeds: [1]\noverrides:\n"
     "  robot*.timeout_duration: [5, 1.0e+308]\n", ":5",
     "override robot*.timeout_duration = 1e+308: 'timeout_duration': timeout_duration must be "
     "between 0.001 and 86400 s"),
    ("application: patrol\nduration: 10\nseeds: [1]\noverrides:\n  robot*.no_such_key: [5]\n",
     ":5", "no key 'no_such_key'"),
])
def test_malformed_files_exit_2_naming_file_and_line(tmp_path, text, where, what):
    f = tmp_path / "exp.yaml"
    f.write_text(text)
    result = CliRunner().invoke(cli, ["experiment", str(f), "--output", str(tmp_path / "o")])
    assert result.exit_code == 2, result.output
    line = result.output.strip().splitlines()[-1]
    assert where in line and what in line, line
    assert not (tmp_path / "o" / "results.csv").exists()


def test_more_seeds_than_max_runs_are_refused_unless_raised(tmp_path):
    """The refusal at a small --max-runs: a file of 10,001 seeds against the default cost
    seconds of YAML parsing for the same code path (the default, MAX_RUNS, is checked on the
    option)."""
    from mrta_supervisor.experiment.cli import run
    from mrta_zenoh.limits import MAX_RUNS
    assert next(p.default for p in run.params if p.name == "max_runs") == MAX_RUNS
    f = tmp_path / "exp.yaml"
    f.write_text("application: patrol\nduration: 10\nseeds: [" + ", ".join(map(str, range(51)))
                 + "]\n")
    result = CliRunner().invoke(cli, ["experiment", str(f), "--output", str(tmp_path / "o"),
                                      "--max-runs", "50"])
    assert result.exit_code == 2 and "more than --max-runs 50" in result.output, result.output
    assert "--max-runs 51" in result.output  # says how to ask for them
    assert not (tmp_path / "o").exists()
    exp = load_experiment(f)
    assert exp.count() == 51
    with pytest.raises(ConfigError, match="more than --max-runs 50"):
        exp.check_runs(50)
    exp.check_runs(51)  # raised: accepted
    exp.check_runs()  # and under the default


def test_an_output_folder_that_cannot_be_made_is_bad_input_not_a_traceback(tmp_path):
    f = tmp_path / "exp.yaml"
    f.write_text("application: patrol\nduration: 10\nseeds: [1]\n")
    result = CliRunner().invoke(cli, ["experiment", str(f), "--output", "/proc/self/x"])
    assert result.exit_code == 2, result.output
    assert "/proc/self/x: --output: cannot make the folder" in result.output
    assert result.exception is None or isinstance(result.exception, SystemExit)


def fake_runs(monkeypatch, n: int):
    """run_experiment replaced by one that reports `n` finished runs, as the real one does."""
    from mrta_supervisor.experiment import cli as experiment_cli
    def fake(*, file, output, progress=None, **_):
        rows = [{"run": i, "status": "ok", "wall_seconds": 1.5 + i} for i in range(n)]
        for i, row in enumerate(rows):
            if progress is not None:
                progress(i + 1, n, row)
        output.mkdir(parents=True, exist_ok=True)
        (output / "summary.md").write_text("# summary\n")
        return rows
    monkeypatch.setattr(experiment_cli, "run_experiment", fake)


def test_progress_goes_to_stderr_one_line_per_run_and_stdout_holds_the_result(tmp_path,
                                                                               monkeypatch):
    fake_runs(monkeypatch, 3)
    f = tmp_path / "exp.yaml"
    f.write_text("application: patrol\nduration: 10\nseeds: [1, 2, 3]\n")
    result = CliRunner().invoke(cli, ["experiment", str(f), "--output", str(tmp_path / "o")])
    assert result.exit_code == 0, result.output
    # the count of runs done, then the run's own name — its folder's and results.csv's `run`
    assert [line for line in result.stderr.splitlines() if line.startswith("[")] == [
        "[1/3] run000 ok, 1.5 s", "[2/3] run001 ok, 2.5 s", "[3/3] run002 ok, 3.5 s"]
    assert "[1/3]" not in result.stdout and "# summary" in result.stdout
    quiet = CliRunner().invoke(cli, ["-q", "experiment", str(f), "--output", str(tmp_path / "o")])
    assert quiet.exit_code == 0 and "[1/3]" not in quiet.stderr and "# summary" in quiet.stdout


def test_mean_and_interval():
    m, h = mean_ci([1.0, 2.0, 3.0])
    assert m == 2.0 and abs(h - 4.302652729911275 / 3 ** 0.5) < 1e-9  # t(0.975, 2)
    # 20 runs: t(0.975, 19) = 2.093, not the 2.0 a table once used for 10-29 df
    xs = [float(i % 5) for i in range(20)]
    m, h = mean_ci(xs)
    sd = (sum((x - m) ** 2 for x in xs) / 19) ** 0.5
    assert abs(h - 2.093024054408263 * sd / 20 ** 0.5) < 1e-9


# ------------------------------------------------------------------ --scheduler (Dask), fast
def _exp_file(tmp_path: Path) -> Path:
    f = tmp_path / "exp.yaml"
    f.write_text("application: patrol\nduration: 10\nseeds: [1]\n")
    return f


def test_scheduler_without_the_dask_extra_exits_2_naming_the_pip_command(tmp_path, monkeypatch):
    import sys
    monkeypatch.setitem(sys.modules, "distributed", None)  # `import distributed` fails
    result = CliRunner().invoke(cli, ["experiment", str(_exp_file(tmp_path)), "--output",
                                      str(tmp_path / "o"), "--scheduler", "tcp://127.0.0.1:1"])
    assert result.exit_code == 2, result.output
    assert "pip install 'mrta-zenoh[dask]'" in result.output
    assert not (tmp_path / "o").exists()  # refused before anything is written


@pytest.mark.parametrize("args,what", [
    (["--scheduler", "tcp://127.0.0.1:1", "--jobs", "2"], "--jobs is for runs on this machine"),
    (["--scheduler", "127.0.0.1"], "expected a Dask scheduler address"),
    (["--scheduler", "tcp://host:port"], "expected a Dask scheduler address"),
])
def test_scheduler_usage_errors_exit_2(tmp_path, args, what):
    result = CliRunner().invoke(cli, ["experiment", str(_exp_file(tmp_path)), "--output",
                                      str(tmp_path / "o"), *args])
    assert result.exit_code == 2 and what in result.output, result.output


def test_a_cluster_without_the_runs_resource_is_refused_and_an_empty_one_waited_for():
    from mrta_zenoh.errors import ConfigError
    from mrta_supervisor.experiment.dask_backend import check_workers

    class Client:
        def __init__(self, workers):
            self.workers = workers

        def scheduler_info(self, n_workers=5):
            return {"workers": self.workers}

    with pytest.raises(ConfigError, match="--resources runs=1"):
        check_workers(Client({"tcp://a:1": {"resources": {}}}), "tcp://s:8786")
    check_workers(Client({"tcp://a:1": {"resources": {"runs": 2}}}), "tcp://s:8786")
    check_workers(Client({}), "tcp://s:8786")  # none yet: a batch system may be starting them


def test_a_run_folder_from_a_worker_stays_inside_its_folder(tmp_path):
    from mrta_zenoh.errors import MrtaRuntimeError
    from mrta_supervisor.experiment.dask_backend import read_folder, write_folder

    src = tmp_path / "src"
    (src / "package" / "config").mkdir(parents=True)
    (src / "run.mcap").write_bytes(b"\x89MCAP")
    (src / "package" / "config" / "r.yaml").write_text("a: 1\n")
    (src / ".mrta-run.lock").write_text("123")
    files = read_folder(src)
    assert set(files) == {"run.mcap", "package/config/r.yaml"}  # the lock is the worker's
    write_folder(tmp_path / "run000", files)
    assert read_folder(tmp_path / "run000") == files
    with pytest.raises(MrtaRuntimeError, match="outside its run folder"):
        write_folder(tmp_path / "run001", {"../evil": b""})
    assert not (tmp_path / "evil").exists() and not (tmp_path / "run001").exists()


def test_an_unreachable_scheduler_is_a_runtime_error(tmp_path):
    import threading

    from mrta_zenoh.errors import MrtaRuntimeError
    from mrta_supervisor.experiment.api import Results
    from mrta_supervisor.experiment.dask_backend import run_on_cluster
    from tests.harness.helpers import free_port

    pytest.importorskip("distributed")
    address = f"tcp://127.0.0.1:{free_port()}"  # nothing listens there
    with pytest.raises(MrtaRuntimeError, match=f"cannot reach the Dask scheduler at {address}"):
        run_on_cluster(address, packages={}, duration=1.0, runs=[], output=tmp_path,
                       stop=threading.Event(), results=Results(tmp_path / "r.csv", 0),
                       connect_timeout=0.1)


def test_results_rows_carry_coordination_and_namespace_traffic_and_older_summaries_still_read(
        tmp_path):
    """results.csv's traffic columns: all samples/s, what robots tell each other, everything
    under the architecture's namespace (a summary from before that count reads as blank)."""
    import json as _json

    from mrta_supervisor.mission.summary import flat_metrics, read_summary
    s = {"mission": "patrol", "application": "patrol", "architecture": "alliance",
         "duration": 10.0, "speed": 0.0, "seed": 1, "wall_seconds": 1.0, "robots": ["robot1"],
         "who_did_what": {"robot1": []}, "first_full_allocation": None, "coverage": {},
         "messages": {"total_per_second": 300.0, "coordination_per_second": 2.0,
                      "coordination_namespace": "alliance"},
         "output": "x", "files": []}
    (tmp_path / "old.json").write_text(_json.dumps(s))
    row = flat_metrics(read_summary(tmp_path / "old.json"))
    assert (row["messages_per_second"], row["coordination_messages_per_second"],
            row["namespace_messages_per_second"]) == (300.0, 2.0, "")
    s["messages"].update(namespace_per_second=150.0,
                         coordination_kinds=["inter_robot_communication"])
    (tmp_path / "new.json").write_text(_json.dumps(s))
    summary = read_summary(tmp_path / "new.json")
    assert flat_metrics(summary)["namespace_messages_per_second"] == 150.0
    assert summary.messages.coordination_kinds == ["inter_robot_communication"]
