"""The one error hierarchy of the library: every error a user should see derives from MrtaError.

Each class carries the exit code a command line ends with when it escapes (docs/architecture.md,
"exit codes"), so the translation is written once — in the root command, mrta_zenoh.cli.main —
and a new error type needs no hand-kept list updated anywhere:

* ConfigError (and what derives from it: field paths, key expressions, ROS 2 names) → 2, bad
  input: usage, a file, a parameter, a value; the message names the file, line and key;
* MrtaRuntimeError → 1: a session that cannot open, a child process that died;
* Interrupted → 130: the user stopped a run (Ctrl-C), as Unix tools report 128 + SIGINT.

Library code raises them; it never prints or exits.
"""

from __future__ import annotations

from typing import ClassVar


class MrtaError(Exception):
    """Base of every user-facing error; `exit_code` is what the `mrta` command exits with."""

    exit_code: ClassVar[int] = 1


class ConfigError(MrtaError):
    """Bad input from the user. The message names the file, line and element (or value) at fault."""

    exit_code: ClassVar[int] = 2

    def __init__(self, message: str, *, file: str | None = None, line: int | None = None,
                 element: str | None = None):
        where = ""
        if file:
            where = f"{file}:{line}: " if line else f"{file}: "
        if element:
            where += f"<{element}>: " if not element.startswith(("<", "'", "\"")) else f"{element}: "
        super().__init__(where + message)
        self.file, self.line, self.element, self.detail = file, line, element, message


class MrtaRuntimeError(MrtaError):
    """Something failed while running (a session could not open, a child process died)."""

    exit_code: ClassVar[int] = 1


class Interrupted(MrtaError):
    """The user stopped a run (Ctrl-C, SIGTERM) before it finished."""

    exit_code: ClassVar[int] = 130
