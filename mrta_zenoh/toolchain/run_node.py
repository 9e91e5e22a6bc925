"""`python -m mrta_zenoh.toolchain.run_node PKG/TYPE ARGS…`: run one registered executable.

`mrta launch` starts every node through this, so a third-party package only registers a click
command under `mrta.executables` to become launchable.
"""

from __future__ import annotations

import sys

import click

from ..cli.common import setup_logging
from .launchfile import executables


def main(argv: list[str]) -> int:
    if not argv:
        print("usage: python -m mrta_zenoh.toolchain.run_node PKG/TYPE [ARGS…]", file=sys.stderr)
        return 2
    name, args = argv[0], argv[1:]
    ep = executables().get(name)
    if ep is None:
        print(f"error: no executable registered as {name!r}", file=sys.stderr)
        return 2
    setup_logging(0)
    target = ep.load()
    if isinstance(target, click.Command):
        return target.main(args=args, prog_name=name, standalone_mode=True) or 0
    return int(target(args) or 0)


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
