"""Regression tests, each failing on the code without its fix.

Some are about behaviour (a duplicate config id accepted, a race in the message registry, a
failed write that lost the old files); others guard a single definition against a second copy
creeping back (one atomic writer, one reader of msgspec's error text, one liveliness prefix, one
time tolerance, a core that names no simulator topic), by reading the source.
"""

import ast
import json
import re
import textwrap
import threading
import time
import types
from importlib.metadata import EntryPoint
from pathlib import Path

import msgspec
import pytest
from click.testing import CliRunner

from mrta_zenoh import codec, messages, secure
from mrta_zenoh.cli.main import cli
from mrta_zenoh.errors import ConfigError
from mrta_zenoh.toolchain.xmlio import load_rqt_mrta
from tests.harness import source_tree
from tests.harness.helpers import ROOT

# Framework and application code (not tests, benchmarks): where the single-definition rules hold.
SOURCES = [ROOT / "mrta_zenoh", ROOT / "robot_agent", ROOT / "simulator", ROOT / "supervisor",
           ROOT / "configs", ROOT / "examples"]


def source_files():
    for folder in SOURCES:
        for f in source_tree.python_files(folder):
            yield f, f.relative_to(ROOT).as_posix()


def constants(path: Path):
    """(node, value) of every constant in a file, docstrings left out (they may quote things)."""
    docstrings = source_tree.docstrings(path)
    return [(n, n.value) for n in source_tree.nodes(path)
            if isinstance(n, ast.Constant) and id(n) not in docstrings]


# --------------------------------------------------------------- 1. duplicate config ids

ARCH = """\
<rqt_mrta>
  <architecture><name>A</name>
    <robots><type>ST</type></robots><tasks><type>SR</type></tasks>
    <allocations><type>IA</type></allocations></architecture>
  <configs>
    <config_0><id>c</id><param_0><name>a</name></param_0></config_0>
    {second}
  </configs>
</rqt_mrta>
"""


@pytest.mark.parametrize("second", [
    "<config_1><id>c</id></config_1>",  # the last config's children were what the check read
    "<config_1><id>c</id>\n      <param_0><name>b</name></param_0></config_1>",  # was: line 8
], ids=["last config empty", "last config with a parameter"])
def test_two_configs_with_one_id_are_refused_at_the_second(tmp_path, second):
    f = tmp_path / "rqt_mrta.xml"
    f.write_text(ARCH.format(second=second))
    with pytest.raises(ConfigError) as err:
        load_rqt_mrta(f)
    assert "config id 'c' is used twice (first on line 6)" in str(err.value)
    assert err.value.file == str(f) and err.value.line == 7, str(err.value)
    assert err.value.element == "<config_1>"
    res = CliRunner().invoke(cli, ["arch", "validate", str(f)])
    assert res.exit_code == 2, res.output
    assert f"{f}:7:" in res.output and "used twice" in res.output


# --------------------------------------------------------- 2. message entry points, racing

def test_concurrent_first_decodes_all_get_the_type_registered_by_entry_point(monkeypatch):
    """Five threads decode a type only an entry point registers, while the loading is slow:
    every one gets the typed class, none GenericMessage (a flag saying "loaded" as soon as
    loading began would show the others a partial registry)."""
    name = "regress_msgs/OnlyByEntryPoint"
    monkeypatch.setattr(messages, "_REGISTRY", dict(messages._REGISTRY))
    monkeypatch.setattr(messages, "_entry_points_loaded", False)
    monkeypatch.setattr(messages, "_entry_point_problems", [])
    ep = EntryPoint(name, "regress_slow_module:Slow", messages.ENTRY_POINT_GROUP)
    monkeypatch.setattr(messages, "entry_points",
                        lambda group: [ep] if group == messages.ENTRY_POINT_GROUP else [])
    started, go = threading.Event(), threading.Event()

    def slow_import(module):  # the module is being imported until the test says go
        assert module == "regress_slow_module"
        started.set()
        go.wait(10)

        @messages.message(name)
        class Slow(messages.Message):
            n: int

        return types.SimpleNamespace(Slow=Slow)

    monkeypatch.setattr(messages, "importlib", types.SimpleNamespace(import_module=slow_import))
    payload = codec.encode_struct({"n": 1})
    results = []

    def decode():
        results.append(codec.decode(name, payload))

    first = threading.Thread(target=decode)
    first.start()
    assert started.wait(10)
    others = [threading.Thread(target=decode) for _ in range(4)]
    for t in others:
        t.start()
    time.sleep(0.3)  # the others are inside the first decode too (a flag set early: generic)
    go.set()
    for t in [first, *others]:
        t.join(10)
    assert len(results) == 5
    assert [type(r).__name__ for r in results] == ["Slow"] * 5
    assert messages.message_class(name) is type(results[0])


# ----------------------------------------------------------------- 3. one atomic writer

def test_a_file_named_like_a_temporary_is_left_alone(tmp_path):
    """A writer using `<name>.tmp` as its temporary would overwrite a user's file of that name,
    then rename it away."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from mrta_zenoh.files import save_figure, write_text

    for name in ("summary.json", "plot.png"):
        (tmp_path / f"{name}.tmp").write_text("mine")
    write_text(tmp_path / "summary.json", "{}")
    fig = plt.figure()
    try:
        save_figure(fig, tmp_path / "plot.png")
    finally:
        plt.close(fig)
    assert (tmp_path / "summary.json").read_text() == "{}"
    assert (tmp_path / "plot.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert {p.name: p.read_text() for p in tmp_path.glob("*.tmp")} == {
        "summary.json.tmp": "mine", "plot.png.tmp": "mine"}
    assert sorted(p.name for p in tmp_path.iterdir()) == [
        "plot.png", "plot.png.tmp", "summary.json", "summary.json.tmp"]  # nothing left over


def test_write_folder_writes_everything_or_nothing(tmp_path):
    from mrta_zenoh.files import write_atomically, write_folder

    dest = tmp_path / "pkg"
    written = write_folder(dest, {"a.txt": b"a", "sub/b.key": b"b"}, modes={"sub/b.key": 0o600})
    assert written == [dest / "a.txt", dest / "sub/b.key"]
    assert (dest / "sub/b.key").stat().st_mode & 0o777 == 0o600

    def half_then_fail(tmp):
        (tmp / "a.txt").write_bytes(b"new")
        raise OSError(5, "Input/output error")

    with pytest.raises(ConfigError, match=f"{re.escape(str(dest))}: cannot write"):
        write_atomically(dest, half_then_fail, folder=True)
    assert (dest / "a.txt").read_bytes() == b"a" and (dest / "sub/b.key").read_bytes() == b"b"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["pkg"]
    write_folder(dest, {"c.txt": b"c"})  # replaces the folder and all it held
    assert sorted(p.name for p in dest.iterdir()) == ["c.txt"]


RENAMES_A_TEMPORARY = re.compile(r"os\.replace\(|os\.rename\(|\.rename\(|mkdtemp\(|mkstemp\(|"
                                 r"NamedTemporaryFile\(|\btmp\w*\.replace\(")


def test_only_the_files_module_moves_temporaries_into_place():
    bad = [f"{rel}:{n}: {line.strip()}"
           for f, rel in source_files() if rel != "mrta_zenoh/files.py"
           for n, line in enumerate(source_tree.text(f).splitlines(), 1)
           if RENAMES_A_TEMPORARY.search(line)]
    assert not bad, "write through mrta_zenoh.files instead:\n" + "\n".join(bad)


# -------------------------------------------------------- 4. msgspec's error text, read once

class _Point(msgspec.Struct, forbid_unknown_fields=True):
    x: int


class _Shape(msgspec.Struct, forbid_unknown_fields=True):
    points: list[_Point]
    names: dict[str, int] = {}
    width: float = 1.0


def _fault(data, kind=_Shape):
    with pytest.raises(msgspec.ValidationError) as err:
        msgspec.convert(data, kind, strict=True)
    return codec.validation_fault(err.value)


@pytest.mark.parametrize("data,expected", [
    ({"points": [{"x": 1}, {"x": "a"}]},
     {"path": ("points", 1, "x"), "expected": "int", "got": "str",
      "what": "Expected `int`, got `str`"}),
    ({"points": [{"x": 1, "y": 2}]}, {"path": ("points", 0), "unknown": "y"}),
    ({"points": [{}]}, {"path": ("points", 0), "missing": "x"}),
    ({}, {"path": (), "missing": "points"}),
    ([], {"path": (), "expected": "object", "got": "array"}),
    ({"points": [], "names": {"a": "b"}}, {"path": ("names", "..."), "expected": "int"}),
    ({"points": [], "names": {1: 2}}, {"path": ("names",), "in_key": True, "expected": "str"}),
])
def test_validation_fault_takes_msgspecs_message_apart(data, expected):
    fault = _fault(data)
    for field, value in expected.items():
        assert getattr(fault, field) == value, (field, fault)


def test_validation_fault_knows_a_non_finite_float():
    fault = _fault({"v": float("nan")}, msgspec.defstruct("F", [("v", messages.Finite)]))
    assert fault.not_finite and fault.path == ("v",)


def test_a_bad_parameter_in_a_list_is_reported_on_its_own_line(tmp_path):
    """Both readers of msgspec's text share its path, list indices as numbers: kept as
    strings by the parameter files' reader, the line would fall back to the list's."""
    from mrta_zenoh.yamlfile import load_yaml

    f = tmp_path / "p.yaml"
    f.write_text(textwrap.dedent("""\
        shape:
          points:
            - x: 1
            - x: oops
        """))
    with pytest.raises(ConfigError) as err:
        load_yaml(f).convert(("shape",), _Shape)
    assert err.value.line == 4 and err.value.element == "'shape/points/1/x'", str(err.value)
    assert "Expected int, got str" in str(err.value)


def test_no_other_module_parses_msgspecs_error_text():
    bad = [f"{rel}:{n}" for f, rel in source_files() if rel != "mrta_zenoh/codec.py"
           for n, line in enumerate(source_tree.text(f).splitlines(), 1)
           if re.search(r"at `\\?\$|missing required field|contains unknown field", line)]
    assert not bad, "use mrta_zenoh.codec.validation_fault:\n" + "\n".join(bad)


# -------------------------------------------------------------- 5. one liveliness prefix

@pytest.mark.slow
def test_the_liveliness_prefix_is_written_once():
    from mrta_zenoh.keys import LIVELINESS_PREFIX

    assert LIVELINESS_PREFIX == "@liveliness/"  # the recordings' format: never change it
    bad = [f"{rel}:{node.lineno}" for f, rel in source_files() if rel != "mrta_zenoh/keys.py"
           for node, value in constants(f)
           if isinstance(value, str) and "@liveliness" in value]
    assert not bad, "use mrta_zenoh.keys.LIVELINESS_PREFIX:\n" + "\n".join(bad)


# ------------------------------------------------------------ 6. one time tolerance

@pytest.mark.slow
def test_time_comparisons_use_the_clocks_epsilon():
    """`t <= stamp + 1e-9`: a time tolerance written out instead of clock.EPSILON. A literal
    elsewhere (a wall's length, nanoseconds to seconds, a division guard) means something else."""
    bad = []
    for f, rel in source_files():
        for node in source_tree.nodes(f):
            if not isinstance(node, ast.Compare):
                continue
            for side in [node.left, *node.comparators]:
                if isinstance(side, ast.BinOp) and isinstance(side.op, (ast.Add, ast.Sub)) and any(
                        isinstance(x, ast.Constant) and x.value == 1e-9
                        for x in (side.left, side.right)):
                    bad.append(f"{rel}:{node.lineno}")
    assert not bad, "use mrta_zenoh.clock.EPSILON:\n" + "\n".join(bad)


# ---------------------------------------------- 7. the core knows no simulator's topics

def test_the_secure_core_names_no_simulator_topic():
    text = (ROOT / "mrta_zenoh" / "secure.py").read_text(encoding="utf-8")
    code = [v for _, v in constants(ROOT / "mrta_zenoh" / "secure.py") if isinstance(v, str)]
    for topic in ("sonar", "odom", "ground_truth", "bumper", "cmd_vel"):
        assert not any(topic in v for v in code), topic
    assert "CLOCK" not in re.sub(r'"""[\s\S]*?"""', "", text)


def _roles(monkeypatch, **specs):
    eps = [types.SimpleNamespace(name=n, value=f"fake:{n}", load=lambda s=s: s)
           for n, s in specs.items()]
    monkeypatch.setattr(secure, "entry_points",
                        lambda group: eps if group == secure.ROLE_GROUP else [])


def test_a_registered_role_gets_exactly_the_keys_it_declares(monkeypatch):
    _roles(monkeypatch, simulator=lambda: {"publish": ["sim/out", "*/scan"],
                                           "tokens": ["@mrta/sim/**"]},
           mapper={"publish": ["map"], "tokens": [], "subscribe": ["*/scan"]})
    sim = secure.rules_for(secure.Identity("simulator", "simulator"))
    assert [r["key_exprs"] for r in sim if r["flows"] == ["ingress"]] == [
        ["sim/out", "*/scan"], ["@mrta/sim/**"], list(secure.EVERYTHING)]
    mapper = secure.rules_for(secure.Identity("mapper", "mapper"))
    by_kind = {tuple(r["messages"]): r["key_exprs"] for r in mapper if r["flows"] == ["ingress"]}
    assert by_kind == {tuple(secure.DATA + secure.ANSWER): ["map"],
                       tuple(secure.SUBSCRIBE): ["*/scan"]}


@pytest.mark.parametrize("spec,text", [
    ({"publish": "clock"}, "must be a list"),
    ({"publish": ["a//b"]}, "empty chunk"),
    ({"pub": []}, "unknown entry 'pub'"),
    (["clock"], "must give a mapping"),
])
def test_a_malformed_role_is_refused_before_any_file(tmp_path, monkeypatch, spec, text):
    _roles(monkeypatch, simulator=spec)
    with pytest.raises(ConfigError, match=text):
        secure.init(tmp_path / "f", ["robot1"], [])
    assert not (tmp_path / "f").exists()


def test_an_unregistered_simulator_role_is_a_config_error(tmp_path, monkeypatch):
    _roles(monkeypatch)
    with pytest.raises(ConfigError, match="no role 'simulator' is registered"):
        secure.init(tmp_path / "f", ["robot1"], [])


def test_the_simulator_registers_its_own_keys(tmp_path):
    """Through the installed entry point: the simulator's rules are the keys it publishes —
    `world` included, which a hand-written list could miss (a secured viewer would have no
    walls)."""
    secure.init(tmp_path / "f", ["robot1"], [])
    router = json.loads((tmp_path / "f" / "router.json5").read_text())
    rules = [r for r in router["access_control"]["rules"] if r["id"].startswith("simulator:")]
    data = next(r for r in rules if "put" in r["messages"])
    assert data["key_exprs"] == ["clock", "*/sonar", "*/odom", "*/ground_truth", "*/bumper",
                                 "world", "@mrta/lockstep/step", "lockstep/status",
                                 "simulator/refused/tally"]  # a token outliving its member
    tokens = next(r for r in rules if r["messages"] == secure.TOKENS)
    assert tokens["key_exprs"] == ["@mrta/clock_source/**", "@mrta/lockstep/barrier/**"]
