"""`python -m mrta_zenoh.tools.mission MODULE:COMMAND ARGS…`: run one application's mission
command (what `mrta.missions` registers) as an experiment's child process."""

from __future__ import annotations

import importlib
import sys

from ..cli.common import setup_logging


def main(argv: list[str]) -> int:
    if not argv or ":" not in argv[0]:
        print("usage: python -m mrta_zenoh.tools.mission MODULE:COMMAND [ARGS…]", file=sys.stderr)
        return 2
    module, _, attr = argv[0].partition(":")
    command = getattr(importlib.import_module(module), attr)
    setup_logging(-1)
    return command.main(args=argv[1:], prog_name="mission", standalone_mode=True) or 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
