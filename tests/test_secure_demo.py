"""`mrta demo --secure FLEET` (issue 51): what a secured run needs of the fleet's folder is said
before any process starts, as the `mrta secure init` options that would write it
(supervisor/mission/secured.py); the options it cannot go with are a usage error. The run
itself: tests/process/test_secure_auctions.py."""

from __future__ import annotations

import json

import pytest
from click.testing import CliRunner

from mrta_supervisor.mission import secured
from mrta_zenoh.cli.main import cli
from mrta_zenoh.errors import ConfigError


def folder_with(tmp_path, *names: str):
    for name in names:
        (tmp_path / f"{name}.json5").write_text("{}")
    return tmp_path


def test_a_fleet_missing_a_process_of_the_run_is_named_as_the_secure_init_option_to_add(
        tmp_path):
    f = folder_with(tmp_path, "router", "simulator", "supervisor", "recorder", "robot1")
    with pytest.raises(ConfigError) as e:
        secured.fleet(f, ["robot1", "robot2"], ["dispatcher"], intake=True)
    text = str(e.value)
    assert "--robot robot2" in text and "--process dispatcher" in text and "--submitter" in text
    assert "--robot robot1" not in text and "--observer" not in text
    assert secured.fleet(f, ["robot1"], [], intake=False).args("robot1") == [
        "--zenoh-config", str(f / "robot1.json5")]


def test_a_folder_that_is_no_fleet_says_how_to_make_one(tmp_path):
    with pytest.raises(ConfigError, match="mrta secure init"):
        secured.fleet(tmp_path, ["robot1"], [], intake=False)


def test_the_fleets_endpoint_is_where_its_router_listens(tmp_path):
    (tmp_path / "router.json5").write_text(json.dumps(
        {"mode": "router", "listen": {"endpoints": ["tls/127.0.0.1:7999"]}}))
    assert secured.Fleet(tmp_path).endpoint == "tls/127.0.0.1:7999"


@pytest.mark.parametrize("extra", [["--rendezvous", "tcp/127.0.0.1:7999"],
                                   ["--agents-per-process", "2"]])
def test_secure_with_a_rendezvous_or_agent_hosts_is_a_usage_error(tmp_path, extra):
    result = CliRunner().invoke(cli, ["demo", "--secure", str(tmp_path), "--output",
                                      str(tmp_path / "out"), *extra])
    assert result.exit_code == 2 and "--secure" in result.output, result.output


def test_a_secured_fleet_with_a_submitter_takes_tasks_at_run_time(tmp_path):
    """With `mrta secure init --submitter NAME` the fleet holds the intake's certificate
    (tasks.json5): the run is reachable — it starts its intake, as `--rendezvous` does, and goes
    on to its duration — so `mrta task submit --as NAME --zenoh-config FLEET/NAME.json5` reaches
    it (issue 51: before, a secured run of an instance with no schedule had no intake).
    tests/process/test_secure_auctions.py submits one through the fleet's router."""
    from mrta_supervisor.mission.hook import MissionOptions
    from mrta_supervisor.mission.runner import reachable
    f = folder_with(tmp_path, "router", "simulator", "supervisor", "recorder")
    assert not reachable(MissionOptions(secure=f)) and not reachable(MissionOptions())
    folder_with(tmp_path, "tasks")
    assert reachable(MissionOptions(secure=f))
    assert reachable(MissionOptions(rendezvous="tcp/127.0.0.1:7999"))
