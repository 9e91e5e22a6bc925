"""A secured fleet runs every feature: the lockstep mission through a
router with mutual TLS and default-deny access control gives, bit for bit, the run an open bus
gives — the simulator's steps, status and world, the agents' StepDone and participant tokens,
the recorder's token all pass; an ACL denying them would run lockstep with 0
participants without a word."""

import signal

import pytest
from click.testing import CliRunner

from mrta_zenoh.bus import BusOptions
from mrta_zenoh.cli.main import cli
from tests.harness.helpers import PATROL, Tokens, free_port
from tests.process.test_lockstep import trace
from tests.test_secure import wait_accepting

pytestmark = pytest.mark.multiprocess

CONFIG = PATROL / "config"
ROBOTS = ("robot1", "robot2", "robot3")


def lockstep_run(children, out, folder=None):
    """Recorder, simulator (lockstep, 16 simulated seconds at full speed) and three agents;
    each with its own fleet config when `folder` is given. Returns the recording's trace."""
    def cfg(name):
        return ["--zenoh-config", folder / f"{name}.json5"] if folder else []

    watcher = Tokens(options=BusOptions(zenoh_config=folder / "recorder.json5")) if folder \
        else Tokens(children.rendezvous)
    try:
        rec = children.mrta("record", "-o", out / "run.mcap", "**", *cfg("recorder"),
                            name="record")
        watcher.wait("@mrta/recorder/*", 60, rec)  # an observer may announce its recorder
        sim = children.mrta("sim", "--world", "patrol",
                            *sum((["--robot", r] for r in ROBOTS), []), "--speed", "0",
                            "--seed", "5", "--duration", "16", "--lockstep",
                            "--wait-robots", "60", *cfg("simulator"), name="sim")
        agents = [children.mrta("agent", r, "--robot-params",
                                CONFIG / f"{r}_alliance_params.yaml",
                                "--tasks-params", CONFIG / "tasks_alliance_params.yaml",
                                "--layers-params", CONFIG / "layers_alliance_params.yaml",
                                "--sim-time", "--seed", "5", *cfg(r), name=r) for r in ROBOTS]
        assert sim.wait(150) == 0, sim.stderr[-15:]
    finally:
        watcher.close()
    assert any("lockstep with 3 participants" in line for line in sim.stderr), sim.stderr[-15:]
    for a in agents:
        a.stop()
    rec.signal(signal.SIGINT)
    assert rec.wait(30) == 130, rec.stderr[-10:]  # stopped as by Ctrl-C; the file is whole
    return trace(out)


@pytest.mark.slow
@pytest.mark.timeout(420)
def test_a_secured_fleet_runs_the_lockstep_mission_as_an_open_bus_does(children, tmp_path):
    folder = tmp_path / "fleet"
    endpoint = f"tls/127.0.0.1:{free_port()}"
    result = CliRunner().invoke(cli, ["secure", "init", str(folder),
                                      *sum((["--robot", r] for r in ROBOTS), []),
                                      "--observer", "recorder", "--endpoint", endpoint])
    assert result.exit_code == 0, result.output
    (tmp_path / "open").mkdir()
    (tmp_path / "secured").mkdir()
    open_run = lockstep_run(children, tmp_path / "open")
    router = children.mrta("router", "--zenoh-config", folder / "router.json5", name="router")
    router.wait_stderr(lambda line: "router listening on tls/" in line, 30)
    wait_accepting(endpoint)
    secured = lockstep_run(children, tmp_path / "secured", folder)
    assert secured[0] == open_run[0] and len(open_run[0]) >= 3   # the same activations
    assert secured[1] == open_run[1] and len(open_run[1]) >= 3 * 7  # the same poses, exactly
