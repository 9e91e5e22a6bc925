import pytest

from mrta_zenoh.bus.options import BusOptions, check_endpoint, session_configs
from mrta_zenoh.errors import ConfigError
from mrta_zenoh.keys import KeyExprError, matches, normalize_robot_id, validate_key_expr


@pytest.mark.parametrize("ep", ["tcp/127.0.0.1:18000", "tcp/[::1]:0", "udp/localhost:9000",
                                "unixsock-stream//tmp/z.sock"])
def test_good_endpoints(ep):
    assert check_endpoint(ep) == ep


@pytest.mark.parametrize("ep,text", [
    ("127.0.0.1:18000", "expected PROTOCOL/ADDRESS"),
    ("tcp/127.0.0.1", "HOST:PORT"),
    ("tcp/127.0.0.1:99999", "port 0-65535"),
    ("http/x:1", "expected PROTOCOL/ADDRESS"),
])
def test_bad_endpoints_name_the_value(ep, text):
    with pytest.raises(ConfigError) as info:
        BusOptions(connect=[ep])
    assert ep in str(info.value) and text in str(info.value)


def test_zero_config_binds_or_joins_the_rendezvous_on_loopback(monkeypatch):
    monkeypatch.setenv("MRTA_RENDEZVOUS", "tcp/127.0.0.1:12345")
    bind, join = session_configs(BusOptions())
    assert bind["listen"]["endpoints"] == ["tcp/127.0.0.1:12345", "tcp/127.0.0.1:0"]
    assert join["connect"]["endpoints"] == ["tcp/127.0.0.1:12345"]
    assert join["listen"]["endpoints"] == ["tcp/127.0.0.1:0"]
    for cfg in (bind, join):
        assert cfg["scouting"]["multicast"]["enabled"] is False


def test_explicit_endpoints_disable_the_rendezvous():
    (cfg,) = session_configs(BusOptions(connect=["tcp/10.0.0.2:18000"]))
    assert cfg["connect"]["endpoints"] == ["tcp/10.0.0.2:18000"]
    assert cfg["listen"]["endpoints"] == ["tcp/127.0.0.1:0"]


def test_user_config_file_merges_over_defaults(tmp_path):
    f = tmp_path / "z.json5"
    f.write_text("{ // comment\n  transport: { link: { tx: { lease: 1000 } } },\n}\n")
    (cfg,) = session_configs(BusOptions(zenoh_config=f))
    assert cfg["transport"]["link"]["tx"]["lease"] == 1000
    assert cfg["scouting"]["multicast"]["enabled"] is False


def test_bad_config_file_names_file_and_line(tmp_path):
    f = tmp_path / "z.json5"
    f.write_text("{\n  mode: 'peer',\n  listen: ,\n}\n")
    with pytest.raises(ConfigError) as info:
        BusOptions(zenoh_config=f).user_config()
    assert str(f) in str(info.value) and "line:3" in str(info.value)
    with pytest.raises(ConfigError, match="cannot read"):
        BusOptions(zenoh_config=tmp_path / "missing.json5").user_config()


@pytest.mark.parametrize("bad", ["", "/a", "a/", "a//b", "a/b*", "a?b", "a#"])
def test_bad_key_expressions(bad):
    with pytest.raises(KeyExprError):
        validate_key_expr(bad)


def test_key_matching():
    assert matches("*/alliance/**", "robot1/alliance/motivation/wander")
    assert matches("robot1/**", "robot1")
    assert not matches("*/cmd_vel", "a/b/cmd_vel")


def test_robot_ids_are_normalised():
    assert normalize_robot_id("/robot1") == "robot1"
    with pytest.raises(KeyExprError):
        normalize_robot_id("robot 1")
