"""`mrta experiment`: a tiny matrix end to end, a failed run, parameter overrides, bad files."""

import csv

import pytest
from click.testing import CliRunner

from mrta_zenoh.cli.main import cli
from mrta_supervisor.experiment import load_experiment, mean_ci


@pytest.mark.multiprocess
@pytest.mark.slow
def test_a_tiny_matrix_gives_one_row_per_run_and_records_a_failed_run(children, tmp_path):
    f = tmp_path / "exp.yaml"
    f.write_text("application: patrol\nduration: 30\nseeds: [1, 2]\n"
                 "failures: [robot2@18, robot9@5]\n")
    out = tmp_path / "out"
    run = children.mrta("experiment", f, "--output", out, "--jobs", "2", name="experiment")
    # four 30-s missions at full speed, two at a time: ≈ 15 s on an idle machine
    assert run.wait(150) == 0, run.stderr[-10:] + run.stdout[-10:]
    rows = list(csv.DictReader((out / "results.csv").open()))
    assert len(rows) == 4
    assert {(r["seed"], r["failure"]) for r in rows} == {
        ("1", "robot2@18"), ("2", "robot2@18"), ("1", "robot9@5"), ("2", "robot9@5")}
    failed = [r for r in rows if r["status"] == "failed"]
    assert {r["failure"] for r in failed} == {"robot9@5"} and all("robot9" in r["error"]
                                                                  for r in failed)
    ok = [r for r in rows if r["status"] == "ok"]
    for r in ok:  # the killed robot's border protection was taken over
        assert r["taken_over_by"] in ("robot1", "robot3") and 0 < float(r["takeover_seconds"]) < 10
        assert float(r["wander.exactly_one"]) > 0.8 and int(r["messages"]) > 1000
    summary = (out / "summary.md").read_text()
    assert "fail=robot2@18" in summary and "Failed runs" in summary
    for name in ("takeover.png", "coverage.png"):
        assert (out / name).stat().st_size > 5_000


def test_overrides_make_one_configuration_per_value(tmp_path):
    f = tmp_path / "exp.yaml"
    f.write_text("application: patrol\nduration: 10\nseeds: [1, 2, 3]\nfailures: [none]\n"
                 "overrides:\n  robot*.timeout_duration: [2.0, 4.0]\n")
    runs = load_experiment(f).runs()
    assert len(runs) == 6 and len({r.config for r in runs}) == 2


def test_an_override_changes_the_files_of_that_run_only(tmp_path):
    import yaml

    from mrta_zenoh.toolchain.registry import Registry
    from mrta_supervisor.experiment import package_copy
    pkg, _ = Registry().application("patrol")
    copy = package_copy(pkg.path, tmp_path, (("robot*.timeout_duration", 4.5),))
    for i in (1, 2, 3):
        doc = yaml.safe_load((copy / "config" / f"robot{i}_alliance_params.yaml").read_text())
        assert doc["timeout_duration"] == 4.5
    original = yaml.safe_load((pkg.path / "config" / "robot1_alliance_params.yaml").read_text())
    assert original["timeout_duration"] != 4.5


@pytest.mark.parametrize("text,where,what", [
    ("application: patrol\nduration: 10\nseeds: [1]\nfailure: [none]\n", ":4", "did you mean 'failures'"),
    ("application: patrol\nduration: -1\nseeds: [1]\n", ":2", "positive"),
    ("application: patrol\nduration: 10\nseeds: [1, x]\n", ":3", "seeds[1]"),
    ("application: patrol\nduration: 10\nseeds: [1]\nfailures: [robot2 at 5]\n", ":4",
     "ROBOT@SECONDS"),
    # accepted here once, then refused by the mission in every run: one grammar now
    ("application: patrol\nduration: 10\nseeds: [1]\nfailures: [none, robot2@0]\n", ":4",
     "seconds > 0"),
    ("application: patrol\nduration: 10\n", "exp.yaml", "missing mandatory key 'seeds'"),
    ("application: patrol\nduration: 10\nseeds: [1]\noverrides: {timeout: [1]}\n", ":4",
     "FILE_GLOB.KEY.PATH"),
])
def test_malformed_files_exit_2_naming_file_and_line(tmp_path, text, where, what):
    f = tmp_path / "exp.yaml"
    f.write_text(text)
    result = CliRunner().invoke(cli, ["experiment", str(f), "--output", str(tmp_path / "o")])
    assert result.exit_code == 2, result.output
    line = result.output.strip().splitlines()[-1]
    assert where in line and what in line, line
    assert not (tmp_path / "o" / "results.csv").exists()


def test_mean_and_interval():
    m, h = mean_ci([1.0, 2.0, 3.0])
    assert m == 2.0 and abs(h - 4.30 * 1.0 / 3 ** 0.5) < 1e-9
