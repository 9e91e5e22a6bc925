"""One error hierarchy and a clean CLI layer.

* Below the command line nothing imports click or mrta_zenoh.cli, prints or exits: library
  code raises, and the CLI layer — mrta_zenoh/cli/ and the verb modules listed here — shows.
  Checked on the source, like tests/test_layering.py.
* Every user-facing error carries its exit code, and the one translation (mrta_zenoh.cli.main)
  gives the same one line and code whichever way a command was started: `mrta VERB`, a launch
  file's node (mrta_zenoh.cli.run_node), or `run` on a bare click command.
"""

import ast
import subprocess
import sys
import textwrap
from pathlib import Path

import click
import pytest
from click.testing import CliRunner

from mrta_zenoh.cli.main import RootGroup, cli, run
from mrta_zenoh.errors import ConfigError, Interrupted, MrtaError, MrtaRuntimeError
from mrta_zenoh.fieldpath import FieldPathError
from mrta_zenoh.keys import KeyExprError
from tests.harness import source_tree
from tests.harness.helpers import ROOT, free_port

# Where the framework's and the shipped applications' code lives.
SOURCES = [ROOT / "mrta_zenoh", ROOT / "robot_agent", ROOT / "simulator", ROOT / "supervisor",
           ROOT / "configs" / "applications"]
CLI_PACKAGE = ROOT / "mrta_zenoh" / "cli"
# The verb modules outside mrta_zenoh/cli/: thin click commands over an api, each registered
# under an entry point (mrta.commands, mrta.executables, mrta.plots). A new one is added here
# on purpose, not by naming a file *cli*.py.
VERB_MODULES = {
    "robot_agent/runtime/cli.py",       # agent_command: the options every agent takes
    "robot_agent/alliance/cli.py",      # mrta agent
    "robot_agent/alliance/plot_cli.py",  # mrta plot motivation
    "robot_agent/murdoch/cli.py",       # mrta murdoch
    "robot_agent/central/cli.py",       # mrta central, mrta dispatcher
    "robot_agent/ssi/cli.py",           # mrta ssi
    "robot_agent/tessi/cli.py",         # mrta tessi
    "robot_agent/cbba/cli.py",          # mrta cbba
    "robot_agent/runtime/host_cli.py",  # mrta host (a robot's arguments parsed by its verb)
    "simulator/cli.py",                 # mrta sim
    "supervisor/live/cli.py",           # mrta supervise, mrta view
    "supervisor/mission/plot_cli.py",   # mrta plot, mrta plot timeline
    "supervisor/mission/cli.py",        # mrta demo
    "supervisor/experiment/cli.py",     # mrta experiment
    "configs/applications/delivery/generate_cli.py",  # python -m mrta_delivery.generate_cli
}


def library_modules() -> list[Path]:
    out = []
    for root in SOURCES:
        for f in source_tree.python_files(root):
            rel = f.relative_to(ROOT).as_posix()
            if CLI_PACKAGE in f.parents or rel in VERB_MODULES:
                continue
            out.append(f)
    return out


def cli_violations(source: str, rel: Path) -> list[str]:
    """What in `source` (the module at `rel`, from the project folder) belongs to the command
    line: importing click or mrta_zenoh.cli (relative imports resolved), calling print(), or
    exiting the process."""
    tree = ast.parse(source)
    package = ["mrta_zenoh", *rel.parts[1:-1]] if rel.parts[0] == "mrta_zenoh" else None
    out = []
    for node in ast.walk(tree):
        names: list[str] = []
        if isinstance(node, ast.Import):
            names = [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            if node.level and package is not None:
                base = package[:len(package) - node.level + 1]
                mod = ".".join(base + ([node.module] if node.module else []))
                names = [mod] + [f"{mod}.{a.name}" for a in node.names]
            elif not node.level:
                names = [node.module or ""]
        elif isinstance(node, ast.Call):
            f = node.func
            if isinstance(f, ast.Name) and f.id in ("print", "exit", "quit"):
                out.append(f"{rel}:{node.lineno}: calls {f.id}()")
            elif isinstance(f, ast.Attribute) and f.attr == "exit" and \
                    isinstance(f.value, ast.Name) and f.value.id in ("sys", "os"):
                out.append(f"{rel}:{node.lineno}: calls {f.value.id}.exit()")
        for n in names:
            if n == "click" or n.startswith("click.") or n == "mrta_zenoh.cli" \
                    or n.startswith("mrta_zenoh.cli."):
                out.append(f"{rel}:{node.lineno}: imports {n}")
                break
    return out


@pytest.mark.slow
def test_nothing_below_the_cli_imports_it_prints_or_exits():
    bad = [v for f in library_modules()
           for v in cli_violations(source_tree.text(f), f.relative_to(ROOT))]
    assert not bad, "\n".join(bad)


def test_the_checker_catches_relative_imports_prints_and_exits():
    """The checker itself, on a module written to break every rule."""
    source = textwrap.dedent("""
        from ..cli.common import plural
        import click
        import sys
        print("x")
        sys.exit(2)
    """)
    found = "\n".join(cli_violations(source, Path("mrta_zenoh/tools/probe.py")))
    for what in ("imports mrta_zenoh.cli.common", "imports click", "calls print()",
                 "calls sys.exit()"):
        assert what in found, found


def test_every_verb_module_listed_exists_and_no_other_module_is_named_like_one():
    for rel in VERB_MODULES:
        assert (ROOT / rel).is_file(), f"{rel} is listed as a verb module but does not exist"
    named_like_verbs = {f.relative_to(ROOT).as_posix() for root in SOURCES
                        for f in root.rglob("*cli*.py") if CLI_PACKAGE not in f.parents}
    assert named_like_verbs <= VERB_MODULES, sorted(named_like_verbs - VERB_MODULES)


# ------------------------------------------------------------------ the one error hierarchy

@pytest.mark.parametrize("error,code", [
    (ConfigError, 2), (FieldPathError, 2), (KeyExprError, 2), (MrtaRuntimeError, 1),
    (Interrupted, 130),
])
def test_every_user_facing_error_carries_its_exit_code(error, code):
    assert issubclass(error, MrtaError) and error.exit_code == code


def group_with(callback) -> click.Group:
    """A root like `mrta`'s with one verb, `do`, that runs `callback`."""
    root = RootGroup()

    @root.command()
    @click.option("--n", type=int, default=0)
    def do(n: int) -> None:
        callback()

    return root


def fail_with(exc: BaseException):
    def callback():
        raise exc
    return callback


TRANSLATIONS = [  # (raised, exit code, the one line on stderr starts with)
    (ConfigError("no such key 'x'", file="robot.yaml", line=3), 2,
     "Error: robot.yaml:3: no such key 'x'"),
    (KeyExprError("key expression 'a b': character ' ' is not allowed"), 2,
     "Error: key expression"),
    (MrtaRuntimeError("cannot open a Zenoh session: boom"), 1,
     "Error: cannot open a Zenoh session"),
    (Interrupted(), 130, "Aborted!"),
    (KeyboardInterrupt(), 130, "Aborted!"),
]
IDS = [type(t[0]).__name__ for t in TRANSLATIONS]


@pytest.mark.parametrize("exc,code,line", TRANSLATIONS, ids=IDS)
def test_the_root_translates_each_error_to_one_line_and_its_code(exc, code, line):
    res = CliRunner().invoke(group_with(fail_with(exc)), ["do"])
    assert res.exit_code == code, res.output
    lines = [x for x in res.output.splitlines() if x.strip()]
    assert len(lines) == 1 and lines[0].startswith(line), res.output


@pytest.mark.parametrize("exc,code,line", TRANSLATIONS, ids=IDS)
def test_a_bare_command_run_standalone_gets_the_same_translation(exc, code, line, capsys):
    """A launch file's node: a plain click command (no group), through `run`."""
    @click.command()
    def node() -> None:
        fail_with(exc)()

    assert run(node, [], prog_name="pkg/node") == code
    lines = [x for x in capsys.readouterr().err.splitlines() if x.strip()]
    assert len(lines) == 1 and lines[0].startswith(line), lines


def test_click_usage_errors_still_exit_2_and_success_exits_0():
    root = group_with(lambda: None)
    res = CliRunner().invoke(root, ["do", "--n", "x"])
    assert res.exit_code == 2 and "Invalid value for '--n'" in res.output
    assert CliRunner().invoke(root, ["nope"]).exit_code == 2
    assert CliRunner().invoke(root, ["do"]).exit_code == 0
    assert CliRunner().invoke(root, ["--help"]).exit_code == 0


def test_an_unexpected_exception_is_not_hidden():
    """A bug is not a user error: it keeps its traceback (CliRunner holds it)."""
    res = CliRunner().invoke(group_with(fail_with(ZeroDivisionError())), ["do"])
    assert isinstance(res.exception, ZeroDivisionError)


# ------------------------------------------------------------------ through the real verbs

BAD_ROBOT = "robot_id: robot1\nbehaviour_sets: [\n"


def bad_agent_args(tmp_path: Path) -> tuple[list[str], Path]:
    robot = tmp_path / "robot1.yaml"
    robot.write_text(BAD_ROBOT)
    tasks = tmp_path / "tasks.yaml"
    tasks.write_text("tasks: []\n")
    return ["robot1", "--robot-params", str(robot), "--tasks-params", str(tasks)], robot


def test_a_bad_config_through_mrta_agent_exits_2_with_one_line_naming_the_file(tmp_path):
    args, robot = bad_agent_args(tmp_path)
    res = CliRunner().invoke(cli, ["agent", *args])
    assert res.exit_code == 2, res.output
    lines = [x for x in res.output.splitlines() if x.strip()]
    assert len(lines) == 1 and lines[0].startswith(f"Error: {robot}:"), res.output


@pytest.mark.slow
@pytest.mark.multiprocess
def test_a_bad_config_through_a_launch_file_node_exits_2_with_the_same_line(tmp_path):
    args, robot = bad_agent_args(tmp_path)
    out = subprocess.run([sys.executable, "-m", "mrta_zenoh.cli.run_node", "robot_agent/agent",
                          *args], capture_output=True, text=True, timeout=120, cwd=ROOT)
    assert out.returncode == 2, out.stderr
    lines = [x for x in out.stderr.splitlines() if x.strip()]
    assert len(lines) == 1 and lines[0].startswith(f"Error: {robot}:"), out.stderr
    unknown = subprocess.run([sys.executable, "-m", "mrta_zenoh.cli.run_node", "nobody/nothing"],
                             capture_output=True, text=True, timeout=120, cwd=ROOT)
    assert unknown.returncode == 2 and "no executable registered" in unknown.stderr


@pytest.mark.slow
@pytest.mark.multiprocess
def test_a_runtime_failure_through_a_launch_file_node_exits_1(tmp_path):
    """The recorder cannot listen where another process already does: a runtime failure."""
    import socket

    port = free_port()
    with socket.socket() as held:
        held.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 0)
        held.bind(("127.0.0.1", port))
        held.listen()
        out = subprocess.run([sys.executable, "-m", "mrta_zenoh.cli.run_node", "mrta_zenoh/record",
                              "-o", str(tmp_path / "r.mcap"), "--duration", "1",
                              "--listen", f"tcp/127.0.0.1:{port}"],
                             capture_output=True, text=True, timeout=120, cwd=ROOT)
    assert out.returncode == 1, out.stderr
    lines = [x for x in out.stderr.splitlines() if x.startswith("Error:")]
    assert len(lines) == 1 and "address already in use" in lines[0], out.stderr
