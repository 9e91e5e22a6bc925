import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from click.testing import CliRunner

from mrta_zenoh.bus.options import MAX_CONFIG_BYTES, BusOptions, check_endpoint, session_configs
from mrta_zenoh.cli.main import cli
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



# ------------------------------------------------------------------ hostile --zenoh-config files
HOSTILE_CONFIGS = [
    ("nested objects", "{a:" * 5000 + "1" + "}" * 5000, None, "nested too deeply"),
    ("nested lists", "{a: " + "[" * 100_000 + "]" * 100_000 + "}", None, "nested too deeply"),
    ("Latin-1", "{\n  mode: 'p\xe9er'}".encode("latin-1"), 2, "not a UTF-8 text file"),
    ("a 5,000-digit number", "{a: " + "9" * 5000 + "}", None, "invalid JSON5"),
    ("a list", "[1]", None, "must be a JSON5 object"),
    ("an unknown key", "{foo: 1}", None, "Zenoh refuses 'foo': unknown key"),
    ("a number for the mode", "{mode: 5}", None, "Zenoh refuses 'mode': invalid type"),
    ("a bad endpoint", "{listen: {endpoints: ['bogus']}}", None, "Endpoints must be of the form"),
    ("NaN in a known section", "{transport: {link: {tx: {lease: NaN}}}}", None,
     "'transport': NaN and Infinity are not numbers"),
]


@pytest.mark.parametrize("text,line,what", [h[1:] for h in HOSTILE_CONFIGS],
                         ids=[h[0] for h in HOSTILE_CONFIGS])
def test_a_hostile_zenoh_config_is_config_error_naming_the_file(tmp_path, text, line, what):
    f = tmp_path / "z.json5"
    f.write_bytes(text if isinstance(text, bytes) else text.encode())
    with pytest.raises(ConfigError) as info:
        BusOptions(zenoh_config=f).check()
    assert info.value.file == str(f) and info.value.line == line, str(info.value)
    assert what in str(info.value) and " at /" not in str(info.value)


def test_a_zenoh_config_larger_than_the_bound_is_not_read(tmp_path):
    f = tmp_path / "z.json5"
    f.write_text("{/*" + " " * MAX_CONFIG_BYTES + "*/}")
    with pytest.raises(ConfigError, match="larger than"):
        BusOptions(zenoh_config=f).user_config()


def test_a_config_zenoh_accepts_passes_the_check(tmp_path):
    f = tmp_path / "z.json5"
    f.write_text("{transport: {link: {tx: {lease: 1000}}}, scouting: {delay: 5}}")
    BusOptions(zenoh_config=f).check()


@pytest.mark.parametrize("verb", [["echo", "x", "--count", "1"], ["record", "-o", "r.mcap"],
                                  ["sim", "--world", "patrol", "--robot", "robot1"]])
def test_commands_exit_2_naming_the_config_file_before_opening_a_session(tmp_path, verb):
    f = tmp_path / "z.json5"
    f.write_text("{mode: 5}")
    result = CliRunner().invoke(cli, [*verb, "--zenoh-config", str(f)])
    assert result.exit_code == 2, result.output
    assert result.output.strip().splitlines()[-1].startswith(f"Error: {f}: Zenoh refuses 'mode'")


@pytest.mark.parametrize("bad", ["", "/a", "a/", "a//b", "a/b*", "a?b", "a#"])
def test_bad_key_expressions(bad):
    with pytest.raises(KeyExprError):
        validate_key_expr(bad)


def test_key_matching():
    assert matches("*/alliance/**", "robot1/alliance/motivation/wander")
    assert matches("robot1/**", "robot1")
    assert not matches("*/cmd_vel", "a/b/cmd_vel")
    assert not matches("**", "@mrta/lockstep/step") and not matches("*/step", "@x/step")
    assert matches("@mrta/**", "@mrta/lockstep/step")
    assert matches("a.b/**/c", "a.b/x/y/c") and not matches("a.b/**/c", "aXb/c")


def _chunk_match(pat: list[str], parts: list[str]) -> bool:
    """The rule, chunk by chunk (matches() compiles it to a regex)."""
    if not pat:
        return not parts
    head = pat[0]
    if head == "**":
        return any(_chunk_match(pat[1:], parts[i:]) for i in range(len(parts) + 1)
                   if not any(p.startswith("@") for p in parts[:i]))
    if not parts:
        return False
    if (head == "*" and not parts[0].startswith("@")) or head == parts[0]:
        return _chunk_match(pat[1:], parts[1:])
    return False


_CHUNKS = st.sampled_from(["a", "b", "@a", "a.b", "(", "robot1", "x*y"])


@pytest.mark.slow
@settings(max_examples=300, derandomize=True, deadline=None)
@given(st.lists(st.one_of(_CHUNKS, st.sampled_from(["*", "**"])), min_size=1, max_size=5),
       st.lists(_CHUNKS, min_size=1, max_size=6))
def test_key_matching_follows_the_chunk_rule(pat, parts):
    assert matches("/".join(pat), "/".join(parts)) == _chunk_match(pat, parts)


def test_robot_ids_are_normalised():
    assert normalize_robot_id("/robot1") == "robot1"
    with pytest.raises(KeyExprError):
        normalize_robot_id("robot 1")
