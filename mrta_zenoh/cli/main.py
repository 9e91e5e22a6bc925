"""`mrta`: one command, subcommands found through the `mrta.commands` entry-point group.

The applications (robot_agent, simulator, supervisor) add their subcommands by entry point, so
the core never imports them, and a pip-installed package can add its own subcommand the same way.
Subcommands are imported only when used: `mrta echo` does not pay for matplotlib.

This is also the one place where the library's errors become exit codes (docs/architecture.md,
"exit codes"): `run` is how every program of the project ends — the `mrta` group, a launch
file's node (mrta_zenoh.cli.run_node) and an experiment's mission (mrta_zenoh.cli.mission) — so
an error means the same one line and the same exit code whichever way a verb was started, and
verbs need no wrapper of their own.
"""

from __future__ import annotations

import sys
from importlib.metadata import entry_points
from typing import Any, Callable, Sequence

import click

from ..errors import Interrupted, MrtaError
from ..lifecycle import die_with_parent, forget_signals, interrupted_by_user
from .common import VERBOSITY_KEY, setup_logging


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


class EntryPointGroup(click.Group):
    """A click group whose subcommands are the entry points of GROUP, loaded when used."""

    GROUP = "mrta.commands"

    def _entry_points(self) -> dict:
        return {ep.name: ep for ep in entry_points(group=self.GROUP)}

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
    ctx.meta[VERBOSITY_KEY] = verbose - quiet
    setup_logging(verbose - quiet)


if __name__ == "__main__":  # `python -m mrta_zenoh.cli.main` = `mrta`, used by tests
    cli()
