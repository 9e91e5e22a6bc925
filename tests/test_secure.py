"""`mrta secure init` and what the generated configs enforce, on loopback, through a real
router (mutual TLS + access control): only certified processes join, a robot speaks only under
its own key, an observer only listens, and the mission runs end to end."""

import json

import pytest
from click.testing import CliRunner

from mrta_zenoh.bus import BusOptions
from mrta_zenoh.cli.main import cli
from tests.helpers import PATROL, Tokens, free_port

CONFIG = PATROL / "config"


@pytest.fixture
def fleet(tmp_path, children):
    endpoint = f"tls/127.0.0.1:{free_port()}"
    folder = tmp_path / "fleet"
    result = CliRunner().invoke(cli, ["secure", "init", str(folder), "--robot", "robot1",
                                      "--robot", "robot2", "--robot", "robot3",
                                      "--observer", "supervisor", "--endpoint", endpoint])
    assert result.exit_code == 0, result.output
    router = children.mrta("router", "--zenoh-config", folder / "router.json5", name="router")
    router.wait_stderr(lambda line: "router listening on tls/" in line, 30)
    return folder, endpoint


def test_init_writes_certificates_and_one_config_per_process(tmp_path):
    folder = tmp_path / "f"
    result = CliRunner().invoke(cli, ["secure", "init", str(folder), "--robot", "robot1",
                                      "--observer", "supervisor"])
    assert result.exit_code == 0, result.output
    names = {p.name for p in folder.iterdir()}
    assert {"ca.pem", "router.json5", "robot1.json5", "simulator.json5", "supervisor.json5",
            "robot1.pem", "robot1.key"} <= names
    router = json.loads((folder / "router.json5").read_text())
    acl = router["access_control"]
    assert acl["enabled"] and acl["default_permission"] == "deny"
    robot_rules = [r for r in acl["rules"] if r["id"].startswith("robot:robot1:")]
    assert any(r["key_exprs"] == ["robot1/**"] and "put" in r["messages"] for r in robot_rules)
    assert router["transport"]["link"]["tls"]["enable_mtls"] is True
    assert (folder / "robot1.key").stat().st_mode & 0o077 == 0  # keys readable by the owner only


@pytest.mark.parametrize("args,text", [
    (["--robot", "robot1", "--robot", "robot1"], "given twice"),
    (["--robot", "robot1", "--endpoint", "tcp/127.0.0.1:7448"], "needs a tls/"),
    (["--observer", "router"], "given twice"),
    ([], "at least one"),
])
def test_bad_requests_write_nothing(tmp_path, args, text):
    folder = tmp_path / "f"
    result = CliRunner().invoke(cli, ["secure", "init", str(folder), "--no-simulator", *args])
    assert result.exit_code == 2 and text in result.output
    assert not folder.exists()


def client(children, config, verb, arg, name):
    return children.python("secure_client.py", config, verb, arg, name=name)


@pytest.mark.multiprocess
@pytest.mark.slow
def test_robots_speak_only_for_themselves_and_observers_only_listen(fleet, children):
    folder, _ = fleet
    watch = client(children, folder / "supervisor.json5", "watch", "12", "observer")
    watch.wait_json(lambda o: o.get("ready"), 30)
    for cfg, key in (("robot1", "robot1/cmd_vel"), ("robot1", "robot2/cmd_vel"),
                     ("supervisor", "robot3/cmd_vel")):
        pub = client(children, folder / f"{cfg}.json5", "pub", key, f"{cfg} → {key}")
        pub.wait_json(lambda o: "published" in o, 30)
    watch.wait(30)
    seen = [json.loads(x) for x in watch.stdout if x.startswith("{")]
    samples = [o["sample"] for o in seen if "sample" in o]
    tokens = {o["token"] for o in seen if o.get("alive")}
    assert samples.count("robot1/cmd_vel") == 10          # its own key: everything arrives
    assert "robot2/cmd_vel" not in samples               # robot1 cannot speak for robot2
    assert "robot3/cmd_vel" not in samples               # an observer cannot publish
    assert "robot1/cmd_vel/token" in tokens              # liveliness: own key only…
    assert "robot2/cmd_vel/token" not in tokens          # …not robot2's
    assert "robot3/cmd_vel/token" not in tokens          # …and observers declare none


@pytest.mark.multiprocess
def test_a_process_without_a_fleet_certificate_cannot_join(fleet, tmp_path, children):
    folder, endpoint = fleet
    other = tmp_path / "other"
    CliRunner().invoke(cli, ["secure", "init", str(other), "--robot", "robot1",
                             "--endpoint", endpoint])
    plain = tmp_path / "plain.json5"
    plain.write_text(json.dumps({"mode": "client", "connect": {
        "endpoints": [endpoint.replace("tls/", "tcp/")]}}))
    for cfg in (other / "robot1.json5", plain):
        echo = children.mrta("echo", "**", "--zenoh-config", cfg, "--count", "1",
                             name=f"echo {cfg.name}")
        assert echo.wait(30) == 1
        assert any("cannot open a Zenoh session" in line for line in echo.stderr), echo.stderr


@pytest.mark.multiprocess
def test_the_mission_runs_with_the_generated_configs(fleet, children):
    folder, _ = fleet
    # tokens seen with an observer's certificate
    watcher = Tokens(options=BusOptions(zenoh_config=folder / "supervisor.json5"))
    try:
        sim = children.mrta("sim", "--world", "patrol", "--robot", "robot1", "--robot", "robot2",
                            "--robot", "robot3", "--speed", "2", "--wait-robots", "60",
                            "--zenoh-config", folder / "simulator.json5", name="sim")
        for i in (1, 2, 3):
            children.mrta("agent", f"robot{i}", "--robot-params",
                          CONFIG / f"robot{i}_alliance_params.yaml",
                          "--tasks-params", CONFIG / "tasks_alliance_params.yaml",
                          "--layers-params", CONFIG / "layers_alliance_params.yaml", "--sim-time",
                          "--zenoh-config", folder / f"robot{i}.json5", name=f"robot{i}")
        watcher.wait("@mrta/clock_source/*", 90, sim)  # up, once its robots were
    finally:
        watcher.close()
    sup = children.mrta("supervise", "patrol", "--sim-time", "--json",
                        "--zenoh-config", folder / "supervisor.json5", name="supervise")
    snap = sup.wait_json(lambda o: sum(r["state"] == "busy" for r in o["robots"]) == 3, 90)
    assert {r["task"] for r in snap["robots"]} == {"wander", "border_protection", "report"}
