"""`mrta`: one command, subcommands found through the `mrta.commands` entry-point group.

The applications (robot_agent, simulator, supervisor) add their subcommands by entry point, so
the core never imports them, and a pip-installed package can add its own subcommand the same way.
Subcommands are imported only when used: `mrta echo` does not pay for matplotlib.
"""

from __future__ import annotations

from importlib.metadata import entry_points

import click

from .common import setup_logging

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


@click.group(cls=EntryPointGroup, context_settings={"help_option_names": ["-h", "--help"]})
@click.option("-v", "--verbose", count=True, help="More log output (-v debug).")
@click.option("-q", "--quiet", count=True, help="Less log output (-q warnings only, -qq errors).")
@click.version_option(package_name="mrta-zenoh")
def cli(verbose: int, quiet: int) -> None:
    """Multi-robot task allocation on Zenoh: agents, simulator, supervisor and config tools."""
    setup_logging(verbose - quiet)


if __name__ == "__main__":  # `python -m mrta_zenoh.cli.main` = `mrta`, used by tests
    cli()
