"""`mrta --help` lists every command without importing any: its lines come
from mrta_zenoh.cli.main.SHORT_HELP, which these tests keep equal to the real commands'. And help
texts agree with the defaults beside them."""

from __future__ import annotations

import json
import subprocess
import sys
from importlib.metadata import entry_points

import pytest
from click.testing import CliRunner

from mrta_zenoh.bus.options import base_config
from mrta_zenoh.cli.main import SHORT_HELP, cli, listed
from mrta_zenoh.lockstep.protocol import DEFAULT_TIMEOUT

GROUPS = ("mrta.commands", "mrta.plots")


def ours() -> list:
    """This distribution's entry points of both listed groups (a third party's are not in the
    table: they are imported to be listed)."""
    return [ep for g in GROUPS for ep in entry_points(group=g)
            if ep.dist is not None and ep.dist.name == "mrta-zenoh"]


def table_line(ep) -> str:
    """The SHORT_HELP line that describes `ep`'s command as it is now."""
    cmd = ep.load()
    text = ("!" + cmd.short_help) if cmd.short_help else (cmd.help or "").split("\n\n")[0]
    return f"    {ep.value!r}: {text!r},"


@pytest.mark.parametrize("ep", ours(), ids=lambda ep: ep.name)
def test_the_table_shows_what_the_command_itself_would(ep):
    assert ep.value in SHORT_HELP, f"add to SHORT_HELP in mrta_zenoh/cli/main.py:\n{table_line(ep)}"
    real, stand_in = ep.load(), listed(ep.name, ep)
    for limit in (20, 45, 60, 80, 200):
        assert stand_in.get_short_help_str(limit) == real.get_short_help_str(limit), \
            f"the command's help changed: in SHORT_HELP write\n{table_line(ep)}"


def test_the_table_holds_no_command_that_is_gone():
    assert set(SHORT_HELP) == {ep.value for ep in ours()}


def test_a_command_the_table_does_not_know_is_loaded_to_be_listed():
    class Fake:
        value = "some_package.cli:verb"

        def load(self):
            import click
            return click.Command("verb", help="A third party's verb. More text.")

    assert listed("verb", Fake()).get_short_help_str(45) == "A third party's verb."


@pytest.mark.multiprocess
def test_help_lists_every_command_and_imports_none(tmp_path):
    """In a fresh interpreter: `mrta --help` names every command with its line, and no module
    of a command (nor the bus, numpy, matplotlib) is imported."""
    script = (
        "import sys, json\n"
        "from mrta_zenoh.cli.main import cli\n"
        "try:\n"
        "    cli.main(['--help'], prog_name='mrta', standalone_mode=False)\n"
        "finally:\n"
        "    print(json.dumps(sorted(sys.modules)))\n")
    out = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True,
                         timeout=120, check=True).stdout
    help_text, modules = out.rsplit("\n", 2)[0], set(json.loads(out.strip().rsplit("\n", 1)[1]))
    commands = [ep for ep in entry_points(group="mrta.commands")]
    for ep in commands:
        assert f"  {ep.name} " in help_text, ep.name
    loaded = {m for m in modules for ep in commands if m == ep.value.split(":")[0]}
    assert not loaded, f"imported for --help: {sorted(loaded)}"
    heavy = {"mrta_zenoh.bus", "mrta_zenoh.codec", "msgspec", "yaml", "numpy", "matplotlib",
             "zenoh", "rich", "mrta_agent", "mrta_simulator", "mrta_supervisor"}
    assert not heavy & modules, sorted(heavy & modules)


def test_help_lines_are_those_click_would_print_from_the_loaded_commands():
    res = CliRunner().invoke(cli, ["--help"], terminal_width=100)
    assert res.exit_code == 0
    listing = res.output.split("Commands:\n", 1)[1].splitlines()
    eps = {ep.name: ep for ep in entry_points(group="mrta.commands")}
    width = max(map(len, eps))
    for line in listing:
        name, text = line.split(maxsplit=1)
        assert text == eps[name].load().get_short_help_str(100 - 6 - width), line


def test_sim_lockstep_timeout_help_agrees_with_its_default_and_the_lease():
    res = CliRunner().invoke(cli, ["sim", "--help"], terminal_width=2000)
    line = next(x for x in res.output.splitlines() if "--lockstep-timeout" in x)
    assert f"[default: {DEFAULT_TIMEOUT}]" in line
    lease = base_config("peer")["transport"]["link"]["tx"]["lease"] / 1000
    assert f"after the {lease:g} s Zenoh lease" in line
    assert "below" not in line  # it once advised a timeout under the lease, beside 30 s
