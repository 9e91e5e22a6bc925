"""Options a user mistypes are usage errors — exit 2, the option and the value named — before
anything starts: seeds outside 0 … 2^63 − 1, and output
paths no run could write (`/proc/x`, `/dev/null/x`, a folder nobody may write in)."""

from __future__ import annotations

import os
from pathlib import Path

import pytest
from click.testing import CliRunner

from mrta_zenoh.cli.common import SEED_TYPE
from mrta_zenoh.cli.main import cli
from mrta_zenoh.errors import ConfigError
from mrta_zenoh.files import check_writable
from mrta_zenoh.seeds import seed_sequence
from tests.harness.helpers import PATROL, free_port

CONFIG = PATROL / "config"
AGENT = ["agent", "robot1", "--robot-params", CONFIG / "robot1_alliance_params.yaml",
         "--tasks-params", CONFIG / "tasks_alliance_params.yaml", "--duration", "0.1"]


def run(*args):
    """In-process, on a private rendezvous: a case that wrongly passes still ends (durations
    are short) and meets nobody."""
    return CliRunner().invoke(cli, list(map(str, args)),
                              env={"MRTA_RENDEZVOUS": f"tcp/127.0.0.1:{free_port()}"})


def assert_usage_error(result, *fragments):
    assert result.exit_code == 2, result.output
    assert result.exception is None or isinstance(result.exception, SystemExit), \
        repr(result.exception)
    assert "Traceback" not in result.output
    last = result.output.strip().splitlines()[-1]
    for f in fragments:
        assert f in last, last


COMMANDS = {
    "demo": ["demo", "--duration", "0.1"],
    "sim": ["sim", "--world", "patrol", "--robot", "robot1", "--duration", "0.1"],
    "agent": AGENT,
}


@pytest.mark.parametrize("seed", ["-1", str(2**63), "99999999999999999999", "9" * 5000, "1.5"])
@pytest.mark.parametrize("command", list(COMMANDS))
def test_a_seed_outside_63_bits_is_a_usage_error(command, seed):
    assert_usage_error(run(*COMMANDS[command], "--seed", seed), "'--seed'")


def test_the_ends_of_the_range_are_seeds_numpy_takes():
    """0 and 2^63 − 1 are seeds (the range is closed), and numpy derives a stream from each."""
    for text in ("0", str(2**63 - 1), " 7 "):
        seed = SEED_TYPE.convert(text, None, None)
        assert seed == int(text)
        seed_sequence(seed, "robot1").generate_state(1)


UNWRITABLE = [
    ("/proc/nope", "cannot write in /proc"),    # mkdir there: ENOENT, even for root
    ("/dev/null/x", "/dev/null is not a folder"),
]
if Path("/sys").is_dir():
    UNWRITABLE.append(("/sys/nope", "cannot write in /sys"))  # root cannot create files there


@pytest.mark.parametrize("path,why", UNWRITABLE, ids=[u[0] for u in UNWRITABLE])
def test_demo_and_experiment_refuse_an_output_folder_they_cannot_make(tmp_path, path, why):
    assert_usage_error(run("demo", "--duration", "0.1", "--output", path), "'--output'", why)
    exp = tmp_path / "e.yaml"
    exp.write_text("application: patrol\nduration: 1\nseeds: [1]\n")
    assert_usage_error(run("experiment", exp, "--output", path), path, "--output")


@pytest.mark.parametrize("path,why", UNWRITABLE, ids=[u[0] for u in UNWRITABLE])
def test_snapshot_and_plots_refuse_a_file_they_cannot_write(tmp_path, path, why):
    png = f"{path}.png" if not path.endswith("/x") else path
    assert_usage_error(run(*COMMANDS["sim"], "--snapshot", png), "'--snapshot'")
    recording = tmp_path / "run.mcap"
    recording.write_bytes(b"")
    assert_usage_error(run("plot", "timeline", recording, "-o", png), "'--output'")
    assert_usage_error(run("plot", "motivation", recording, "--robot", "robot1", "--task",
                           "wander", "-o", png), "'--output'")


def test_a_snapshot_into_a_folder_that_does_not_exist(tmp_path):
    assert_usage_error(run(*COMMANDS["sim"], "--snapshot", tmp_path / "no" / "w.png"),
                       "folder", "does not exist")


@pytest.mark.skipif(os.geteuid() == 0, reason="root writes into a folder of mode 0555")
def test_a_read_only_folder_is_refused(tmp_path):
    ro = tmp_path / "ro"
    ro.mkdir()
    ro.chmod(0o555)
    try:
        assert_usage_error(run("demo", "--duration", "0.1", "--output", ro / "out"),
                           "Permission denied")
        assert_usage_error(run(*COMMANDS["sim"], "--snapshot", ro / "w.png"),
                           "Permission denied")
    finally:
        ro.chmod(0o755)


def test_check_writable_leaves_nothing_behind_and_makes_nothing(tmp_path):
    check_writable(tmp_path / "a" / "b", folder=True)
    check_writable(tmp_path / "w.png", folder=False)
    assert list(tmp_path.iterdir()) == []
    (tmp_path / "f").write_text("x")
    with pytest.raises(ConfigError, match="is not a folder"):
        check_writable(tmp_path / "f" / "sub", folder=True)
    with pytest.raises(ConfigError, match="is a folder, not a file"):
        check_writable(tmp_path, folder=False)


@pytest.mark.parametrize("args,option", [(["--seed", "-1"], "'--seed'"),
                                         (["--rate", "nan"], "'--rate'"),
                                         (["--rate", "0"], "'--rate'"),
                                         (["--output", "/dev/null/x"], "'--output'")])
def test_the_delivery_generator_takes_the_same_checked_options(tmp_path, args, option):
    from mrta_delivery.generate_cli import main

    argv = ["--arrivals", "poisson", "--name", "x", "--output", str(tmp_path), *args]
    assert_usage_error(CliRunner().invoke(main, argv), option)
    assert list(tmp_path.iterdir()) == []


def test_demo_rendezvous_is_checked_and_bare_means_the_shared_one(monkeypatch):
    """`mrta demo --rendezvous`: a malformed endpoint is bad input naming the option; bare, it
    is the rendezvous every command meets at ($MRTA_RENDEZVOUS); absent, the run is private."""
    from mrta_zenoh.errors import ConfigError
    from mrta_supervisor.mission.cli import shared_rendezvous
    with pytest.raises(ConfigError, match="--rendezvous endpoint 'nonsense'"):
        shared_rendezvous("nonsense")
    monkeypatch.setenv("MRTA_RENDEZVOUS", "tcp/127.0.0.1:17999")
    assert shared_rendezvous("") == "tcp/127.0.0.1:17999"
    assert shared_rendezvous("tcp/127.0.0.1:18000") == "tcp/127.0.0.1:18000"
    assert shared_rendezvous(None) is None
