"""Hostile YAML in every file a user hands us — parameter, world, experiment, answers files:
one line naming the file and the line, exit 2; never a traceback.

What YAML can say beyond plain data (complex keys, dates, sets, binary, integers longer than
Python converts, characters it forbids) is refused by the one loader, mrta_zenoh.yamlfile, and a
property feeds random YAML to the real readers: each returns or raises ConfigError."""

from __future__ import annotations

import string
from pathlib import Path

import pytest
from click.testing import CliRunner
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from mrta_agent.alliance.params import load_robot_params
from mrta_agent.runtime.params import load_layers_params, load_tasks_params
from mrta_simulator.world import load_world
from mrta_supervisor.experiment.api import load_experiment
from mrta_zenoh.cli.main import cli
from mrta_zenoh.errors import ConfigError
from mrta_zenoh.yamlfile import MAX_BYTES, load_yaml
from tests.harness.alliance_fixtures import robot_yaml, tasks_yaml, write
from tests.harness.helpers import free_port

# (name, the text, the line the error names, a fragment of its message)
HOSTILE = [
    ("complex key", "name: w\n? [a, b]\n: 1\n", 2, "not a list (YAML complex key)"),
    ("complex key in a flow mapping", "name: w\nx: {[a, b]: 1}\n", 2, "YAML complex key"),
    ("mapping as key", "name: w\n? {a: 1}\n: 1\n", 2, "not a mapping"),
    ("integer of 5,000 digits", "name: w\nx: " + "9" * 5000 + "\n", 2, "too long"),
    ("NUL byte", "name: w\nx: a\x00b\n", 2, "character NUL is not allowed"),
    ("control character", "name: w\n\nx: a\x07b\n", 3, "#x0007"),
    ("date key", "name: w\n2020-01-01: 3\n", 2, "is read as a date"),
    ("number key", "name: w\n1: 3\n", 2, "is read as a number"),
    ("null key", "name: w\n~: 3\n", 2, "is read as null"),
    ("boolean key", "name: w\nyes: 3\n", 2, "is read as a boolean"),
    ("date key merged in", "name: w\n<<: {2020-01-01: 3}\n", 2, "is read as a date"),
    ("date value", "name: w\nx: 2020-01-01\n", 2, "quote it if it is text"),
    ("!!set", "name: w\nx: !!set {a, b}\n", 2, "!!set is not allowed"),
    ("!!binary", "name: w\nx: !!binary aGVsbG8=\n", 2, "!!binary is not allowed"),
    ("!!omap", "name: w\nx: !!omap [a: 1]\n", 2, "!!omap is not allowed"),
    ("a python tag", "name: w\nx: !!python/object:os.system 1\n", 2, "constructor"),
    ("Latin-1 text", "name: w\nx: caf\xe9\n".encode("latin-1"), 2, "not a UTF-8 text file"),
]


def _write(path: Path, text: str | bytes) -> Path:
    if isinstance(text, bytes):
        path.write_bytes(text)
    else:
        path.write_text(text)
    return path


@pytest.mark.parametrize("text,line,what", [h[1:] for h in HOSTILE], ids=[h[0] for h in HOSTILE])
def test_the_loader_names_file_and_line(tmp_path, text, line, what):
    f = _write(tmp_path / "f.yaml", text)
    with pytest.raises(ConfigError) as info:
        load_yaml(f)
    assert info.value.file == str(f) and info.value.line == line, str(info.value)
    assert what in str(info.value) and "\n" not in str(info.value)


def test_plain_data_still_loads_and_quoted_keys_are_text(tmp_path):
    f = _write(tmp_path / "f.yaml", "'1': [1, 2.5, true, null, '2020-01-01']\n"
                                    "base: {a: 1}\nmerged:\n  <<: {a: 1, b: 2}\n  b: 3\n")
    assert load_yaml(f).data == {"1": [1, 2.5, True, None, "2020-01-01"], "base": {"a": 1},
                                 "merged": {"a": 1, "b": 3}}


def test_a_file_larger_than_the_bound_is_not_read(tmp_path):
    f = tmp_path / "big.yaml"
    with f.open("w") as out:
        out.write("x: '")
        out.write("a" * MAX_BYTES)
        out.write("'\n")
    with pytest.raises(ConfigError, match="larger than") as info:
        load_yaml(f)
    assert info.value.file == str(f)


# ----------------------------------------------------------- through the commands, exit 2
def run(*args):
    return CliRunner().invoke(cli, list(map(str, args)),
                              env={"MRTA_RENDEZVOUS": f"tcp/127.0.0.1:{free_port()}"})


def assert_bad_input(result, *fragments):
    assert result.exit_code == 2, result.output
    assert "Traceback" not in result.output
    lines = result.output.strip().splitlines()
    assert len(lines) == 1, result.output
    for f in fragments:
        assert f in lines[0], lines[0]


BAD = "? [a, b]\n: 1\n"


def test_world_file_with_a_complex_key(tmp_path):
    w = _write(tmp_path / "w.yaml", "name: w\n" + BAD)
    assert_bad_input(run("sim", "--world", w, "--robot", "robot1", "--duration", "0.1"),
                     f"{w}:2:", "YAML complex key")


def test_experiment_file_with_a_date_key(tmp_path):
    e = _write(tmp_path / "e.yaml", "application: patrol\nduration: 5\nseeds: [1]\n"
                                    "2020-01-01: 1\n")
    assert_bad_input(run("experiment", e, "--output", tmp_path / "out"), f"{e}:4:", "a date")
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize("which", ["robot", "tasks", "layers"])
def test_parameter_files_with_a_long_integer(tmp_path, which):
    robot = write(tmp_path / "robot.yaml", robot_yaml([{"task": "wander", "fast": 10.0}]))
    tasks = write(tmp_path / "tasks.yaml", tasks_yaml(["wander"], {"wander": ["patrol/wander"]}))
    layers = _write(tmp_path / "layers.yaml", "Wander: {speed: 0.5}\n")
    bad = {"robot": robot, "tasks": tasks, "layers": layers}[which]
    lines = bad.read_text().count("\n")
    bad.write_text(bad.read_text() + "extra: " + "7" * 4400 + "\n")
    assert_bad_input(run("agent", "robot1", "--robot-params", robot, "--tasks-params", tasks,
                         "--layers-params", layers, "--duration", "1"),
                     f"{bad}:{lines + 1}:", "too long")


# ----------------------------------------------------------- random YAML: never a traceback
_SCALARS = st.sampled_from(["1", "-3", "2.5", ".nan", ".inf", "true", "no", "~", "null", "''",
                            "2020-01-01", "0x1F", "0o17", "1e999", "9" * 4400, "a", "'x: y'",
                            "!!binary aGk=", "!!set {a}", "!!str 5", "!!int x", "&a 1", "*a",
                            "\x00", "\u200b", "é", "[]", "{}", "- x", "|\n  text"])
_KEYS = st.sampled_from(["name", "walls", "robots", "size", "sensor0", "plugin_name", "tasks",
                         "task0", "id", "layers", "seeds", "duration", "application",
                         "failures", "overrides", "behaviour_sets", "spin_rate", "Wander",
                         "speed", "1", "2020-01-01", "? [a]", "? {b: 1}", "<<", "~", "true",
                         "polygon", "segment", "starts", "border", "robot1"])


def _node(depth: int):
    if depth == 0:
        return _SCALARS
    inner = _node(depth - 1)
    return st.one_of(
        _SCALARS,
        st.lists(inner, max_size=3).map(lambda xs: "[" + ", ".join(xs) + "]"),
        st.lists(st.tuples(_KEYS, inner), max_size=3).map(
            lambda kv: "{" + ", ".join(f"{k}: {v}" for k, v in kv) + "}"))


_DOC = st.one_of(
    st.lists(st.tuples(_KEYS, _node(3)), min_size=1, max_size=6).map(
        lambda kv: "".join(f"{k}: {v}\n" for k, v in kv)),
    st.text(alphabet=string.printable + "\x00\x85é[]{}:-?&*!|>'\"", max_size=80))

READERS = {
    "load_yaml": load_yaml,
    "world": load_world,
    "experiment": load_experiment,
    "robot params": load_robot_params,
    "tasks params": load_tasks_params,
    "layers params": load_layers_params,
}


@pytest.mark.slow
@pytest.mark.parametrize("reader", list(READERS))
@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow,
                                                                    HealthCheck.function_scoped_fixture])
@given(text=_DOC)
def test_random_yaml_gives_config_error_or_data_never_a_traceback(tmp_path, reader, text):
    f = tmp_path / "random.yaml"
    f.write_text(text, encoding="utf-8", errors="surrogatepass")
    try:
        READERS[reader](f)
    except ConfigError as exc:
        assert str(f) in str(exc)
