"""Error types shared by the library and the CLI.

The CLI maps them to exit codes: ConfigError (bad input: usage, files, parameters) → 2,
MrtaRuntimeError → 1. Library code raises them; it never prints or exits.
"""

from __future__ import annotations


class MrtaError(Exception):
    pass


class ConfigError(MrtaError):
    """Bad input from the user. The message names the file, line and element (or value) at fault."""

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


class Interrupted(MrtaError):
    """The user stopped a run (Ctrl-C, SIGTERM) before it finished."""
