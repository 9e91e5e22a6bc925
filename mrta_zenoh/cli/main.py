"""`mrta`: one command, subcommands found through the `mrta.commands` entry-point group.

The applications (robot_agent, simulator, supervisor) add their subcommands by entry point, so
the core never imports them, and a pip-installed package can add its own subcommand the same way.
Subcommands are imported only when used: `mrta echo` does not pay for matplotlib, and `mrta
--help` imports none of them — it lists them with their short help from SHORT_HELP, a table of
this distribution's commands that tests/test_cli_help.py keeps equal to the real ones (importing
every verb to print one line each cost 1.3–1.5 s of CPU; a third party's command not in the table
is imported to show its line).

This is also the one place where the library's errors become exit codes (docs/architecture.md,
"Exit codes"): `run` is how every program of the project ends — the `mrta` group (an
experiment's runs too: each is an `mrta demo` child), a launch file's node
(mrta_zenoh.cli.run_node) and an application's own script (mrta_delivery.generate_cli) — so
an error means the same one line and the same exit code whichever way a verb was started, and
verbs need no wrapper of their own.
"""

from __future__ import annotations

import sys
from typing import Any, Callable, Sequence

import click

from ..errors import Interrupted, MrtaError
from ..installed import entry_points
from ..lifecycle import die_with_parent, forget_signals, interrupted_by_user


def report(exc: BaseException) -> int:
    """Say what went wrong on stderr, in one line where the error is one, and return the exit
    code for it: an MrtaError's own, click's for its exceptions (usage errors: 2), 130 for
    Ctrl-C."""
    if isinstance(exc, Interrupted):
        click.echo(f"Aborted! {exc}" if str(exc) else "Aborted!", err=True)
        return exc.exit_code
    if isinstance(exc, MrtaError):
        click.echo(f"Error: {exc}", err=True)
        return exc.exit_code
    if isinstance(exc, click.ClickException):
        exc.show()
        return exc.exit_code
    if isinstance(exc, click.Abort):  # click's own: Ctrl-C, or end of input at a prompt
        click.echo("Aborted!", err=True)
        return Interrupted.exit_code if isinstance(exc.__cause__, KeyboardInterrupt) else 1
    raise TypeError(f"not an error to report: {exc!r}")


def run(command: click.Command, args: Sequence[str] | None = None,
        prog_name: str | None = None, **extra: Any) -> int:
    """Run `command` as a program; return its exit code instead of exiting.

    click's standalone mode would exit 1 with a traceback on our errors; here they are reported
    by `report`. A command may return an int: its exit code (click's `ctx.exit(n)` too)."""
    die_with_parent()
    forget_signals()
    try:
        rv = command.main(args=list(args) if args is not None else None, prog_name=prog_name,
                          standalone_mode=False, **extra)
    except (MrtaError, click.ClickException, click.Abort) as exc:
        return report(exc)
    return _exit_code(rv)


def _exit_code(rv: Any) -> int:
    """A command's return value as an exit code; a run that a SIGINT (Ctrl-C) ended — however
    cleanly it then shut down — exits 130, as Unix tools do, so a script or a parent can tell
    an interrupted run from a finished one (lifecycle.interrupted_by_user)."""
    code = rv if type(rv) is int else 0
    return Interrupted.exit_code if code == 0 and interrupted_by_user() else code


def run_callable(target: Callable[[list[str]], Any], args: list[str]) -> int:
    """An executable registered as a plain function of argv (not a click command): the same
    reporting of our errors."""
    die_with_parent()
    forget_signals()
    try:
        rv = target(args)
    except MrtaError as exc:
        return report(exc)
    except KeyboardInterrupt:
        return report(Interrupted())
    return _exit_code(rv)


# Entry-point value → the first paragraph of its command's help (or its short_help, marked by a
# leading "!"): what `mrta --help` and `mrta plot --help` show without importing the commands.
# tests/test_cli_help.py fails, printing the line to write, when a command of this distribution
# is missing or its help changed.
SHORT_HELP = {
    "mrta_zenoh.cli.task:task":
        "Tasks at run time: submit, cancel, reprioritise and list a running mission's tasks.",
    "mrta_agent.alliance.cli:agent":
        "Run ROBOT_ID's ALLIANCE agent: motivational behaviours, sensors, evaluators and layers.",
    "mrta_zenoh.cli.toolchain:app": "Registered MRTA applications; create new ones.",
    "mrta_zenoh.cli.toolchain:arch": "Registered MRTA architectures (rqt_mrta's plugins).",
    "mrta_supervisor.mission.cli:demo":
        "A mission end to end: simulator, agents and supervisor, then a summary.",
    "mrta_zenoh.cli.echo:echo": "!Print the samples on a key expression or ROS topic.",
    "mrta_supervisor.experiment.cli:experiment":
        "!Run an experiment file's matrix of runs, or rebuild its report.",
    "mrta_zenoh.cli.instance:instance":
        "Problem instances: generate them, look at them, check them (`mrta demo --instance`).",
    "mrta_zenoh.cli.toolchain:launch":
        "Run a launch file: `mrta launch PACKAGE FILE.launch [name:=value …]` or a path.",
    "mrta_agent.murdoch.cli:murdoch":
        "Run ROBOT_ID's MURDOCH agent: auctions, leases, sensors, evaluators and layers.",
    "mrta_agent.central.cli:central":
        "Run ROBOT_ID's central agent: serve the queue the dispatcher sends, report progress "
        "(sensors, evaluators and layers as every agent).",
    "mrta_agent.central.cli:dispatcher":
        "Run central's dispatcher: it re-solves the problem at each arrival, completion or "
        "robot loss and sends each robot its queue (docs/central.md). Its faults come from "
        "$MRTA_FAULTS, e.g. crash:dispatcher@T.",
    "mrta_agent.ssi.cli:ssi":
        "Run ROBOT_ID's SSI agent: bid in sequential single-item auctions (clear them as the "
        "lowest-id live robot), serve the path its awards built.",
    "mrta_agent.cbba.cli:cbba":
        "Run ROBOT_ID's CBBA agent: build its bundle, reach consensus with its teammates, "
        "serve its bundle's path.",
    "mrta_agent.tessi.cli:tessi":
        "Run ROBOT_ID's TeSSI agent: bid the makespan of its temporal network with a task "
        "inserted in sequential single-item auctions, serve the resulting schedule.",
    "mrta_agent.runtime.host_cli:host":
        "Run the agents of the robots SPEC lists in this one process (an agent host): each robot "
        "keeps its keys, tokens, parameters, seed stream and faults; one Zenoh session and one "
        "lockstep participant serve them all.",
    "mrta_supervisor.mission.plot_cli:plot":
        "Plots from a recording made with `mrta record` (or `mrta demo`).",
    "mrta_zenoh.cli.record:record":
        "Record every sample on KEYEXPR… (default: everything) to an MCAP file.",
    "mrta_zenoh.cli.replay:replay":
        "Republish RECORDING's bus channels with their original timing (rosbag play).",
    "mrta_zenoh.cli.ros2:ros2":
        "ROS 2 robots over rmw_zenoh, with no ROS 2 installation (docs/ros2.md).",
    "mrta_zenoh.cli.router:router":
        "Run a Zenoh router, listening on the rendezvous endpoint unless told otherwise.",
    "mrta_zenoh.cli.secure:secure":
        "Authenticated, authorised fleets: certificates and Zenoh configs (docs/security.md).",
    "mrta_simulator.cli:sim":
        "Simulate Pioneer 3-DX robots: cmd_vel in; clock, sonar, odom, ground_truth, bumper out.",
    "mrta_supervisor.live.cli:supervise":
        "Supervise APP (a registered application or its rqt_mrta.xml): robots, tasks, alarms,\n"
        "    and the ROS 2 graph (a robot whose ROS 2 driver node is gone is offline).",
    "mrta_supervisor.live.cli:view":
        "Serve APP's robots, scene and supervisor to Foxglove (ws://HOST:PORT), live.",
    # `mrta plot` kinds (mrta.plots)
    "mrta_agent.alliance.plot_cli:motivation":
        "rqt_alliance's seven panels for one robot and task, over time.",
    "mrta_supervisor.mission.plot_cli:timeline":
        "Which robot did which task when (a Gantt chart), with offline periods hatched.",
}


def listed(name: str, ep) -> click.Command:
    """What a help listing shows for the entry point `ep`: a stand-in holding its short help
    when SHORT_HELP knows the command, the loaded command otherwise."""
    text = SHORT_HELP.get(ep.value)
    if text is None:
        return ep.load()
    if text.startswith("!"):
        return click.Command(name, short_help=text[1:])
    return click.Command(name, help=text)


class EntryPointGroup(click.Group):
    """A click group whose subcommands are the entry points of GROUP, loaded when used."""

    GROUP = "mrta.commands"

    def _entry_points(self) -> dict:
        return {ep.name: ep for ep in entry_points(group=self.GROUP)}

    def format_commands(self, ctx: click.Context, formatter: click.HelpFormatter) -> None:
        """click's listing of subcommands, with each line from SHORT_HELP where it can be
        (`listed`), so that `--help` imports no subcommand."""
        eps = self._entry_points()
        rows = []
        for name in self.list_commands(ctx):
            held = super().get_command(ctx, name)
            cmd = held if held is not None else listed(name, eps[name])
            if cmd is not None and not cmd.hidden:
                rows.append((name, cmd))
        if rows:
            limit = formatter.width - 6 - max(len(name) for name, _ in rows)
            with formatter.section("Commands"):
                formatter.write_dl([(name, cmd.get_short_help_str(limit)) for name, cmd in rows])

    def list_commands(self, ctx: click.Context) -> list[str]:
        return sorted(set(super().list_commands(ctx)) | set(self._entry_points()))

    def get_command(self, ctx: click.Context, name: str) -> click.Command | None:
        cmd = super().get_command(ctx, name)
        if cmd is not None:
            return cmd
        ep = self._entry_points().get(name)
        return ep.load() if ep is not None else None

    def resolve_command(self, ctx: click.Context, args: list[str]) -> tuple:
        """click's, with "Did you mean 'demo'?" for a mistyped command: click suggests from the
        commands it holds, and ours are entry points it does not hold."""
        try:
            return super().resolve_command(ctx, args)
        except click.exceptions.NoSuchCommand as exc:
            raise click.exceptions.NoSuchCommand(
                exc.command_name, possibilities=self.list_commands(ctx), ctx=ctx) from None


class RootGroup(EntryPointGroup):
    """`mrta` itself: in standalone mode (a console script, `python -m`, CliRunner) it exits
    through `run`, so every verb's errors are translated here and nowhere else."""

    def main(self, args: Sequence[str] | None = None, prog_name: str | None = None,
             complete_var: str | None = None, standalone_mode: bool = True, **extra: Any) -> Any:
        if not standalone_mode:
            return super().main(args, prog_name, complete_var, standalone_mode=False, **extra)
        sys.exit(run(self, args, prog_name, complete_var=complete_var, **extra))


@click.group(cls=RootGroup, context_settings={"help_option_names": ["-h", "--help"]})
@click.option("-v", "--verbose", count=True, help="More log output (-v debug).")
@click.option("-q", "--quiet", count=True,
              help="Quieter: -q no progress output and warnings only, -qq errors only.")
@click.version_option(package_name="mrta-zenoh")
@click.pass_context
def cli(ctx: click.Context, verbose: int, quiet: int) -> None:
    """Multi-robot task allocation on Zenoh: agents, simulator, supervisor and config tools."""
    from .common import VERBOSITY_KEY, setup_logging  # not for `mrta --help`: it imports the bus

    ctx.meta[VERBOSITY_KEY] = verbose - quiet
    setup_logging(verbose - quiet)


if __name__ == "__main__":  # `python -m mrta_zenoh.cli.main` = `mrta`, used by tests
    cli()
