"""Parameter overrides on runs of an instance (supervisor/mission/overrides.py): a run derives its
packages from its instance into its own folder, and the overrides are set there — in the run's
architecture's package only, never in an installed package; an experiment passes its cell's
overrides to each run of an instance as `mrta demo --override`. The mission itself is replaced
by a stand-in (no process)."""

from __future__ import annotations

import re
from pathlib import Path

import pytest
import yaml
from click.testing import CliRunner

from mrta_zenoh import instances
from mrta_zenoh.cli.main import cli
from mrta_zenoh.errors import ConfigError
from mrta_zenoh.toolchain.registry import Registry
from mrta_supervisor.mission import runner as mission
from mrta_supervisor.experiment.file import load_experiment
from mrta_supervisor.experiment.api import prepare_experiment
from mrta_supervisor.experiment.runs import start_run
from mrta_supervisor.mission.hook import MissionOptions
from mrta_supervisor.mission.runner import run_mission
from mrta_supervisor.mission.overrides import override_text, parse_override


@pytest.fixture
def instance(tmp_path) -> Path:
    path = tmp_path / "inst.yaml"
    instances.generate("delivery", {"robots": 3, "tasks": 4}, 7, path)
    return path


@pytest.fixture
def no_launch(monkeypatch):
    """The mission's launch replaced: records the run it would have started."""
    started = []

    def _run_in(run, reg, stop, progress, before):
        started.append(run)
        return run, None

    monkeypatch.setattr(mission, "_run_in", _run_in)
    return started


def params(folder: Path, package: str, name: str) -> dict:
    return yaml.safe_load((folder / package / "config" / name).read_text())


def test_an_instance_runs_overrides_are_set_in_its_own_derived_package(tmp_path, instance,
                                                                        no_launch):
    installed = Registry().find("delivery_murdoch").path / "config"
    before = {f.name: f.read_bytes() for f in installed.glob("*.yaml")}
    out = tmp_path / "run"
    run_mission(MissionOptions(application="delivery", architecture="murdoch", output=out,
                               instance=instance,
                               overrides=(("robot*.lease_timeout", 3.5),
                                          ("robot*.utility.skill_weight", 2.0))))
    derived = out / "instance"
    assert [r.package.path.parent for r in no_launch] == [derived]  # the run reads that copy
    for rid in ("robot1", "robot2", "robot3"):
        doc = params(derived, "delivery_murdoch", f"{rid}_murdoch_params.yaml")
        assert doc["lease_timeout"] == 3.5 and doc["utility"]["skill_weight"] == 2.0
    # the installed package and the other architectures' derived packages are untouched
    assert {f.name: f.read_bytes() for f in installed.glob("*.yaml")} == before
    alliance = params(derived, "delivery", "robot1_alliance_params.yaml")
    assert alliance["timeout_duration"] == 2.0


@pytest.mark.parametrize("key,what", [
    ("nothing*.lease_timeout", "no parameter file of package 'delivery_murdoch' matches "
                               "'nothing*'"),
    ("robot*.lease_timout", "no key 'lease_timout'"),
])
def test_an_override_matching_nothing_in_the_instances_package_is_an_error(
        tmp_path, instance, no_launch, key, what):
    with pytest.raises(ConfigError, match=re.escape(what)):
        run_mission(MissionOptions(application="delivery", architecture="murdoch",
                                   output=tmp_path / "run", instance=instance,
                                   overrides=((key, 1.0),)))
    assert no_launch == []


def test_demo_refuses_an_override_without_an_instance(tmp_path, no_launch):
    result = CliRunner().invoke(cli, ["demo", "--application", "delivery", "--override",
                                      "robot*.timeout_duration=4.0", "--output",
                                      str(tmp_path / "o"), "--no-live"])
    assert result.exit_code == 2, result.output
    assert "--override sets parameters of the packages a run derives" in result.output
    assert no_launch == [] and not (tmp_path / "o").exists()


@pytest.mark.parametrize("text", ["robot*.x", "=3", "robot.=3", ".x=3"])
def test_a_malformed_override_is_a_usage_error(text):
    with pytest.raises(ConfigError, match="expected FILE_GLOB.KEY.PATH=VALUE"):
        parse_override(text)


@pytest.mark.parametrize("value", [2.0, 2, "2", True, "a b", [1, 2.5], None])
def test_an_override_goes_through_the_command_line_with_its_type(value):
    assert parse_override(override_text("robot*.k", value)) == ("robot*.k", value)


class Group:
    """A process group that records what it was asked to start."""

    def __init__(self):
        self.started = []

    def start(self, argv, name, env, merge_stderr):
        self.started.append((argv, env))


def test_an_experiment_gives_each_instance_run_its_cells_overrides(tmp_path):
    f = tmp_path / "exp.yaml"
    f.write_text("application: delivery\narchitecture: alliance\nduration: 10\nseeds: [1]\n"
                 "instances: {generator: delivery, robots: [2], count: 1, seed: 3}\n"
                 "overrides:\n  robot*.timeout_duration: [2.0, 4.0]\n")
    exp, resolved, _ = prepare_experiment(load_experiment(f), tmp_path / "o")
    group = Group()
    for run in exp.runs():
        out = tmp_path / f"r{run.index}"
        out.mkdir()
        start_run(group, resolved[None].package, 10.0, run, out)
    got = [argv[argv.index("--override") + 1] for argv, _ in group.started]
    assert got == ["robot*.timeout_duration=2.0", "robot*.timeout_duration=4.0"]
    assert all("--instance" in argv for argv, _ in group.started)
    # no copy of the installed package: the run derives its own
    assert all("MRTA_PACKAGE_PATH" not in env for _, env in group.started)
    assert not list(tmp_path.glob("r*/package"))


def test_an_experiment_refuses_an_override_its_instances_packages_lack(tmp_path):
    f = tmp_path / "exp.yaml"
    f.write_text("application: delivery\narchitecture: central\nduration: 10\nseeds: [1]\n"
                 "instances: {generator: delivery, robots: [2], count: 1, seed: 3}\n"
                 "overrides:\n  robot*.timeout_duration: [4.0]\n")
    result = CliRunner().invoke(cli, ["experiment", str(f), "--output", str(tmp_path / "o")])
    assert result.exit_code == 2, result.output
    line = result.output.strip().splitlines()[-1]
    assert "exp.yaml:7" in line and "no key 'timeout_duration'" in line, line
    assert not (tmp_path / "o" / "results.csv").exists()
