"""`python -m mrta_zenoh.cli.run_node PKG/TYPE ARGS…`: run one registered executable (rosrun).

`mrta launch` starts every node through this, so a third-party package only registers a click
command under `mrta.executables` to become launchable. It lives in the CLI layer because it is a
program: it ends through mrta_zenoh.cli.main.run, so a node's bad config exits 2 with the same
one line as `mrta VERB` would print, and a runtime failure exits 1.
"""

from __future__ import annotations

import sys

import click

from ..errors import ConfigError
from ..toolchain.launchfile import executables
from .common import setup_logging
from .main import report, run, run_callable

USAGE = "usage: python -m mrta_zenoh.cli.run_node PKG/TYPE [ARGS…]"


def main(argv: list[str]) -> int:
    if not argv:
        click.echo(USAGE, err=True)
        return 2
    name, args = argv[0], argv[1:]
    ep = executables().get(name)
    if ep is None:
        return report(ConfigError(f"no executable registered as {name!r}"))
    setup_logging(0)
    target = ep.load()
    if isinstance(target, click.Command):
        return run(target, args, prog_name=name)
    return run_callable(target, args)


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
