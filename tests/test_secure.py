"""`mrta secure init` and what the generated configs enforce, on loopback, through a real
router (mutual TLS + access control): only certified processes join, a robot speaks only under
its own key, an observer only listens, and the mission runs end to end."""

import json
import os
import socket
import time
from pathlib import Path

import pytest
from click.testing import CliRunner
from cryptography import x509
from cryptography.x509.oid import ExtendedKeyUsageOID

from mrta_zenoh import secure
from mrta_zenoh.bus import BusOptions
from mrta_zenoh.cli.main import cli
from mrta_zenoh.errors import ConfigError
from mrta_zenoh.identity import check_identity
from mrta_zenoh.keys import matches
from tests.harness.helpers import PATROL, ROOT, Tokens, free_port

CONFIG = PATROL / "config"


def allowed(router: dict, name: str, message: str, key: str) -> bool:
    """Would the router let `name` send `message` (put, liveliness_token…) on `key`?"""
    acl = router["access_control"]
    subjects = {s["id"] for s in acl["subjects"] if name in s["cert_common_names"]}
    rules = {rid for p in acl["policies"] if set(p["subjects"]) & subjects for rid in p["rules"]}
    return any(r["id"] in rules and message in r["messages"] and "ingress" in r["flows"]
               and any(matches(e, key) for e in r["key_exprs"]) for r in acl["rules"])


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
    wait_accepting(endpoint)
    return folder, endpoint


def wait_accepting(endpoint: str, timeout: float = 30) -> None:
    """Until the router's port accepts TCP connections: it may say it listens a moment before
    it does, and a client (unlike a peer) fails at once when nobody answers."""
    host, port = endpoint.split("/", 1)[1].rsplit(":", 1)
    deadline = time.monotonic() + timeout
    while True:
        try:
            socket.create_connection((host, int(port)), timeout=1).close()
            return
        except OSError:
            if time.monotonic() > deadline:
                raise
            time.sleep(0.05)


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
    assert allowed(router, "robot1", "put", "robot1/cmd_vel")
    assert not allowed(router, "robot1", "put", "robot2/cmd_vel")
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


@pytest.mark.slow
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


# ------------------------------------------------------------------ every feature has its keys
def test_every_role_may_use_the_keys_its_features_need_and_no_more(tmp_path):
    """Lockstep (before: the simulator could not step nor report, robots could not answer nor
    join: lockstep ran with 0 participants), the recorder's and the viewer's token, the world,
    a robot's own ROS 2 driver, and a bridge for its robots only."""
    secure.init(tmp_path / "f", ["robot1", "robot2"], ["recorder"], bridges=["robot1"])
    r = json.loads((tmp_path / "f" / "router.json5").read_text())
    yes = [("simulator", "put", "@mrta/lockstep/step"), ("simulator", "put", "lockstep/status"),
           ("simulator", "put", "world"), ("simulator", "put", "clock"),
           ("simulator", "liveliness_token", "@mrta/lockstep/barrier/run1"),
           ("simulator", "liveliness_token", "@mrta/clock_source/run1"),
           ("robot1", "put", "@mrta/lockstep/done/robot1"),
           ("robot1", "liveliness_token", "@mrta/lockstep/participant/robot1"),
           ("robot1", "put", "0/robot1/odom/nav_msgs::msg::dds_::Odometry_/RIHS01_x"),
           ("robot1", "liveliness_token", "@ros2_lv/0/z/1/1/NN/%/%robot1/driver"),
           ("recorder", "liveliness_token", "@mrta/recorder/0123abcd"),
           ("recorder", "declare_liveliness_subscriber", "@ros2_lv/0/z/1/1/NN/%/%robot1/d"),
           ("bridge-robot1", "put", "robot1/odom"), ("bridge-robot1", "put", "robot1/sonar"),
           ("bridge-robot1", "put", "0/robot1/cmd_vel/geometry_msgs::msg::dds_::Twist_/R"),
           ("bridge-robot1", "liveliness_token", "@mrta/ros2_bridge/robot1"),
           ("bridge-robot1", "liveliness_token",
            "@ros2_lv/0/z/1/1/NN/%/%/mrta_bridge_robot1"),
           ("bridge-robot1", "liveliness_token",
            "@ros2_lv/0/z/1/2/MP/%/%/mrta_bridge_robot1/%robot1%cmd_vel/t/h/q")]
    no = [("robot1", "put", "@mrta/lockstep/done/robot2"),
          ("robot1", "put", "@mrta/lockstep/step"),
          ("robot1", "liveliness_token", "@mrta/lockstep/participant/robot2"),
          ("robot1", "liveliness_token", "@mrta/clock_source/run1"),
          ("robot1", "put", "0/robot2/cmd_vel/x/y"),
          ("robot1", "liveliness_token", "@ros2_lv/0/z/1/1/NN/%/%robot2/fake_driver"),
          ("recorder", "put", "robot1/cmd_vel"), ("recorder", "put", "lockstep/status"),
          ("recorder", "liveliness_token", "robot1/alliance/agent"),
          ("simulator", "put", "robot1/cmd_vel"),
          ("simulator", "put", "@mrta/lockstep/done/robot1"),
          ("bridge-robot1", "put", "robot2/odom"), ("bridge-robot1", "put", "robot1/cmd_vel"),
          ("bridge-robot1", "put", "0/robot2/cmd_vel/x/y"),
          ("bridge-robot1", "liveliness_token", "robot1/alliance/agent"),
          ("bridge-robot1", "liveliness_token", "@mrta/ros2_bridge/robot2"),
          ("bridge-robot1", "liveliness_token", "@ros2_lv/0/z/1/1/NN/%/%robot1/fake_driver")]
    assert [x for x in yes if not allowed(r, *x)] == []
    assert [x for x in no if allowed(r, *x)] == []


def test_only_the_router_certificate_can_serve_and_clients_verify_its_name(tmp_path):
    secure.init(tmp_path / "f", ["robot1"], ["supervisor"], bridges=["robot1"],
                endpoint="tls/10.1.2.3:7448")
    f = tmp_path / "f"

    def cert(name):
        return x509.load_pem_x509_certificate((f / f"{name}.pem").read_bytes())

    def eku(c):
        return set(c.extensions.get_extension_for_class(x509.ExtendedKeyUsage).value)

    router = cert("router")
    assert ExtendedKeyUsageOID.SERVER_AUTH in eku(router)
    sans = router.extensions.get_extension_for_class(x509.SubjectAlternativeName).value
    assert {str(i) for i in sans.get_values_for_type(x509.IPAddress)} == {"10.1.2.3"}
    for name in ("robot1", "supervisor", "simulator", "bridge-robot1"):
        c = cert(name)
        assert eku(c) == {ExtendedKeyUsageOID.CLIENT_AUTH}, name  # never a server
        try:
            alt = c.extensions.get_extension_for_class(x509.SubjectAlternativeName).value
        except x509.ExtensionNotFound:
            alt = None
        assert alt is None or not (alt.get_values_for_type(x509.DNSName)
                                   or alt.get_values_for_type(x509.IPAddress)), name
        tls = json.loads((f / f"{name}.json5").read_text())["transport"]["link"]["tls"]
        assert tls["verify_name_on_connect"] is True


def test_configs_name_the_certificates_under_root_so_the_folder_can_be_copied(tmp_path):
    secure.init(tmp_path / "f", ["robot1"], [], root="/etc/mrta/fleet")
    for name in ("router", "robot1", "simulator"):
        text = (tmp_path / "f" / f"{name}.json5").read_text()
        assert str(tmp_path) not in text
        tls = json.loads(text)["transport"]["link"]["tls"]
        assert tls["root_ca_certificate"] == "/etc/mrta/fleet/ca.pem"
        assert tls["connect_certificate"] == f"/etc/mrta/fleet/{name}.pem"
    result = CliRunner().invoke(cli, ["secure", "init", str(tmp_path / "g"), "--robot", "r1",
                                      "--root", "relative/dir"])
    assert result.exit_code == 2 and "absolute path" in result.output
    assert not (tmp_path / "g").exists()


# ------------------------------------------------------------------ --force and other files
def test_force_replaces_only_the_files_secure_init_writes(tmp_path):
    folder = tmp_path / "fleet"
    secure.init(folder, ["robot1"], [], simulator=False)
    (folder / "notes.txt").write_text("mine")
    (folder / "sub").mkdir()
    (folder / "sub" / "x").write_text("x")
    old_ca = (folder / "ca.pem").read_bytes()
    result = CliRunner().invoke(cli, ["secure", "init", str(folder), "--robot", "robot1",
                                      "--no-simulator"])
    assert result.exit_code == 2 and "--force" in result.output and "ca.pem" in result.output
    assert (folder / "ca.pem").read_bytes() == old_ca
    secure.init(folder, ["robot1", "robot2"], [], simulator=False, force=True)
    assert (folder / "notes.txt").read_text() == "mine" and (folder / "sub" / "x").exists()
    assert (folder / "ca.pem").read_bytes() != old_ca and (folder / "robot2.pem").exists()
    assert not [p for p in folder.iterdir() if p.name.startswith(".")]  # nothing left behind


def test_init_in_the_current_folder_leaves_its_other_files_alone(tmp_path, monkeypatch):
    """Before: `mrta secure init . --force` emptied the current folder, then failed."""
    monkeypatch.chdir(tmp_path)
    Path("project.py").write_text("keep me")
    for args in (["--robot", "robot1"], ["--robot", "robot1", "--force"]):
        result = CliRunner().invoke(cli, ["secure", "init", ".", *args])
        assert result.exit_code == 0, result.output
        assert Path("project.py").read_text() == "keep me" and Path("robot1.pem").exists()
    assert sorted(p.name for p in tmp_path.iterdir() if p.name.startswith(".")) == []


def test_a_failed_replacement_puts_every_old_file_back(tmp_path, monkeypatch):
    folder = tmp_path / "fleet"
    secure.init(folder, ["robot1"], [], simulator=False)
    (folder / "notes.txt").write_text("mine")
    before = {p.name: p.read_bytes() for p in folder.iterdir()}
    real = os.replace
    moved = []

    def fail_on_the_fourth(src, dst):
        moved.append(dst)
        if len(moved) == 4:  # robot1.pem, after ca.pem, ca.key and router.pem were replaced
            raise OSError(28, "No space left on device")
        return real(src, dst)

    monkeypatch.setattr(os, "replace", fail_on_the_fourth)
    with pytest.raises(ConfigError, match="No space left on device"):
        secure.init(folder, ["robot1", "robot2"], [], simulator=False, force=True)
    assert {p.name: p.read_bytes() for p in folder.iterdir()} == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["fleet"]


@pytest.mark.slow
@pytest.mark.parametrize("args,text", [
    (["--bridge", "robot9"], "not a --robot"),
    (["--bridge", "b=robot1,robot1"], "given twice"),
    (["--bridge", "robot1", "--observer", "bridge-robot1"], "given twice"),
    (["--bridge", "=,"], "expected ROBOT"),
])
def test_bad_bridges_write_nothing(tmp_path, args, text):
    folder = tmp_path / "f"
    result = CliRunner().invoke(cli, ["secure", "init", str(folder), "--robot", "robot1", *args])
    assert result.exit_code == 2 and text in result.output, result.output
    assert not folder.exists()


# ------------------------------------------------------------------ a certificate not one's own
@pytest.mark.parametrize("config,role,name,robots,text", [
    ("robot2", "robot", "robot1", (), "is for robot robot2, not for robot robot1"),
    ("supervisor", "robot", "robot1", (), "is for observer supervisor, not for robot robot1"),
    ("robot1", "observer", None, (), "is for robot robot1, not for an observer"),
    ("robot1", "simulator", None, (), "is for robot robot1, not for the simulator"),
    ("bridge-robot1", "bridge", None, ("robot2",), "a bridge for robot1, not for robot2"),
])
def test_a_process_with_another_identity_s_certificate_is_refused(tmp_path, config, role, name,
                                                                  robots, text):
    secure.init(tmp_path / "f", ["robot1", "robot2"], ["supervisor"], bridges=["robot1"])
    opts = BusOptions(zenoh_config=tmp_path / "f" / f"{config}.json5")
    with pytest.raises(ConfigError, match=text.replace("(", r"\(")) as err:
        check_identity(opts, role, name, robots)
    assert f"{config}.json5" in str(err.value)


@pytest.mark.slow
def test_the_right_certificate_or_an_open_bus_passes_and_a_missing_one_says_root(tmp_path):
    secure.init(tmp_path / "f", ["robot1"], ["supervisor"], bridges=["b=robot1"],
                root=str(tmp_path / "elsewhere"))
    (tmp_path / "elsewhere").symlink_to(tmp_path / "f")
    f = tmp_path / "f"
    check_identity(BusOptions(zenoh_config=f / "robot1.json5"), "robot", "robot1")
    check_identity(BusOptions(zenoh_config=f / "supervisor.json5"), "observer")
    check_identity(BusOptions(zenoh_config=f / "simulator.json5"), "simulator")
    check_identity(BusOptions(zenoh_config=f / "b.json5"), "bridge", robots=["robot1"])
    check_identity(BusOptions(), "robot", "robot1")          # an open bus: nothing to check
    (tmp_path / "elsewhere").unlink()                        # the folder is not where it says
    with pytest.raises(ConfigError, match="--root"):
        check_identity(BusOptions(zenoh_config=f / "robot1.json5"), "robot", "robot1")


def test_a_bridge_started_with_another_bridge_s_certificate_refuses_to_start(tmp_path):
    secure.init(tmp_path / "f", ["robot1", "robot2"], [], bridges=["robot1"])
    result = CliRunner().invoke(cli, ["ros2", "bridge", "--robot", "robot2", "--zenoh-config",
                                      str(tmp_path / "f" / "bridge-robot1.json5")])
    assert result.exit_code == 2
    assert "a bridge for robot1, not for robot2" in result.output


def with_endpoint(src: Path, dst: Path, endpoint: str, cert: str | None = None) -> Path:
    cfg = json.loads(src.read_text())
    key = "listen" if cfg["mode"] == "router" else "connect"
    cfg[key]["endpoints"] = [endpoint]
    if cert:
        tls = cfg["transport"]["link"]["tls"]
        tls["listen_certificate"], tls["listen_private_key"] = f"{cert}.pem", f"{cert}.key"
    dst.write_text(json.dumps(cfg))
    return dst


def can_join(children, config: Path, name: str) -> bool:
    echo = children.python("secure_client.py", config, "watch", "0.2", name=name)
    code = echo.wait(30)
    assert code == 0 or any("cannot open a Zenoh session" in line for line in echo.stderr), \
        echo.stderr[-5:]
    return code == 0


@pytest.mark.slow
@pytest.mark.multiprocess
def test_a_robot_certificate_cannot_pose_as_the_router(tmp_path, children):
    """A client-only certificate (extended key usage clientAuth) is refused as a server even
    by a client that trusts the CA: robot1's key cannot run a router its teammates would join.
    The router's own certificate, at the same address, is accepted (the control)."""
    f = tmp_path / "f"
    secure.init(f, ["robot1"], ["supervisor"])
    endpoint = f"tls/127.0.0.1:{free_port()}"
    client = with_endpoint(f / "supervisor.json5", tmp_path / "client.json5", endpoint)
    for cert, joins in ((f / "robot1", False), (f / "router", True)):
        cfg = with_endpoint(f / "router.json5", tmp_path / f"{cert.name}-router.json5",
                            endpoint, str(cert))
        router = children.mrta("router", "--zenoh-config", cfg, name=f"{cert.name} as router")
        router.wait_stderr(lambda line: "router listening on tls/" in line, 30)
        wait_accepting(endpoint)
        assert can_join(children, client, f"client of {cert.name}") is joins
        router.stop()


@pytest.mark.slow
@pytest.mark.multiprocess
def test_clients_verify_the_router_s_name(tmp_path, children):
    """The router's certificate names `localhost` (the endpoint given): reached as 127.0.0.1,
    an address it does not name, a client refuses it; reached as localhost, it joins."""
    f = tmp_path / "f"
    port = free_port()
    secure.init(f, ["robot1"], ["supervisor"], endpoint=f"tls/localhost:{port}")
    router = children.mrta("router", "--zenoh-config",
                           with_endpoint(f / "router.json5", tmp_path / "r.json5",
                                         f"tls/127.0.0.1:{port}"), name="router")
    router.wait_stderr(lambda line: "router listening on tls/" in line, 30)
    wait_accepting(f"tls/127.0.0.1:{port}")
    by_ip = with_endpoint(f / "supervisor.json5", tmp_path / "ip.json5", f"tls/127.0.0.1:{port}")
    assert can_join(children, f / "supervisor.json5", "by name")
    assert not can_join(children, by_ip, "by address")


@pytest.mark.slow
@pytest.mark.parametrize("command,config", [
    (["agent", "robot1", "--robot-params", "{cfg}/robot1_alliance_params.yaml",
      "--tasks-params", "{cfg}/tasks_alliance_params.yaml"], "robot2"),
    (["sim", "--world", "patrol", "--robot", "robot1"], "robot1"),
    (["supervise", "patrol", "--once"], "robot1"),
    (["record", "-o", "{tmp}/x.mcap"], "robot1"),
    (["view", "patrol", "--no-server", "--output", "{tmp}/x.mcap", "--duration", "1"], "robot2"),
])
def test_every_process_refuses_a_certificate_that_is_not_its_own(tmp_path, command, config):
    """Without the check a process is muted without a word: the router drops what the
    certificate may not say. Each process checks before its bus opens (and before any file is written)."""
    secure.init(tmp_path / "f", ["robot1", "robot2"], ["supervisor"])
    cfg = ROOT / "configs" / "applications" / "patrol" / "config"
    args = [a.format(cfg=cfg, tmp=tmp_path) for a in command]
    result = CliRunner().invoke(cli, [*args, "--zenoh-config",
                                      str(tmp_path / "f" / f"{config}.json5")])
    assert result.exit_code == 2, result.output
    assert f"{config}.json5" in result.output and "not for" in result.output
    assert not (tmp_path / "x.mcap").exists()


def test_force_removes_the_previous_fleets_files_and_nothing_else(tmp_path):
    """robot1's certificate from an earlier fleet, signed by a CA that no longer exists, must
    not stay beside the new fleet; files secure init never wrote stay whatever happens."""
    folder = tmp_path / "f"
    secure.init(folder, ["robot1"], ["sup"])
    (folder / "mine.txt").write_text("keep me")
    secure.init(folder, ["robot2"], [], force=True)
    names = {p.name for p in folder.iterdir()}
    assert not names & {"robot1.pem", "robot1.key", "robot1.json5", "sup.pem", "sup.json5"}
    assert {"robot2.pem", "robot2.json5", "mine.txt", "ca.pem"} <= names
    assert (folder / "mine.txt").read_text() == "keep me"


def test_central_on_a_secured_fleet_only_the_dispatcher_sends_queues(tmp_path):
    """Issue 51.4: `mrta secure init` had no dispatcher role, so central could not run on a
    secured fleet at all. `--process dispatcher` gives it its certificate and the role central
    registers (mrta_agent.central.secure_role): it sends the queues, its decisions and its
    tallies, answers lockstep; no robot may send a queue, the dispatcher no robot's progress."""
    result = CliRunner().invoke(cli, ["secure", "init", str(tmp_path / "f"), "--robot", "robot1",
                                      "--robot", "robot2", "--process", "dispatcher"])
    assert result.exit_code == 0, result.output
    r = json.loads((tmp_path / "f" / "router.json5").read_text())
    yes = [("dispatcher", "put", "dispatcher/central/queue/robot1"),
           ("dispatcher", "put", "dispatcher/central/plan"),
           ("dispatcher", "put", "dispatcher/refused/tally"),
           ("dispatcher", "put", "@mrta/lockstep/done/dispatcher"),
           ("dispatcher", "liveliness_token", "@mrta/node/dispatcher"),
           ("dispatcher", "liveliness_token", "@mrta/lockstep/participant/dispatcher"),
           ("robot1", "put", "robot1/central/progress")]
    no = [("robot1", "put", "dispatcher/central/queue/robot2"),
          ("robot1", "liveliness_token", "@mrta/node/dispatcher"),
          ("robot2", "put", "robot1/central/progress"),
          ("dispatcher", "put", "robot1/central/progress"),
          ("dispatcher", "put", "robot1/delivery/done"),
          ("dispatcher", "put", "@mrta/lockstep/step"),
          ("dispatcher", "liveliness_token", "@mrta/lockstep/participant/robot1")]
    assert [x for x in yes if not allowed(r, *x)] == []
    assert [x for x in no if allowed(r, *x)] == []
    opts = BusOptions(zenoh_config=tmp_path / "f" / "robot1.json5")
    with pytest.raises(ConfigError, match="is for robot robot1, not for the dispatcher"):
        check_identity(opts, "dispatcher", "dispatcher")
    check_identity(BusOptions(zenoh_config=tmp_path / "f" / "dispatcher.json5"), "dispatcher",
                   "dispatcher")
    bad = CliRunner().invoke(cli, ["secure", "init", str(tmp_path / "g"), "--robot", "robot1",
                                   "--process", "dispatchr"])
    assert bad.exit_code == 2 and "no role 'dispatchr' is registered" in bad.output
    assert not (tmp_path / "g").exists()
