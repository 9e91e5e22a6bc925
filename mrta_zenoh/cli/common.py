"""What every subcommand shares: the bus options, logging, checked numbers and plurals.

The library's errors are mapped to exit codes once, in the root command (mrta_zenoh.cli.main):
a verb lets them propagate instead of wrapping its body.
"""

from __future__ import annotations

import functools
import logging
import math
from pathlib import Path
from typing import Any, Callable

import click

from ..bus.options import MODES, BusOptions
from ..errors import ConfigError
from ..files import check_writable
from ..limits import SEED
from ..untrusted import visible
from ..yamlfile import plural  # noqa: F401 - the verbs import it from here


def bus_options(f: Callable | None = None) -> Callable:
    """Add --connect/--listen/--mode/--zenoh-config/--namespace and pass `bus_options=BusOptions`.
    `--namespace` is the bus prefix in every command (the bridge's ROS 2 namespace is its own
    `--ros-namespace`)."""

    def decorate(f: Callable) -> Callable:
        @click.option("--connect", "connect", multiple=True, metavar="ENDPOINT",
                      help="Zenoh endpoint to connect to (repeatable), e.g. tcp/192.168.1.10:7447.")
        @click.option("--listen", "listen", multiple=True, metavar="ENDPOINT",
                      help="Zenoh endpoint to listen on (repeatable). Default: tcp/127.0.0.1:0, "
                           "and the rendezvous endpoint while nobody holds it.")
        @click.option("--mode", type=click.Choice(MODES[:2]), default="peer", show_default=True,
                      help="Zenoh session mode.")
        @click.option("--zenoh-config", type=click.Path(dir_okay=False, path_type=Path),
                      metavar="FILE.json5",
                      help="Zenoh configuration file (merged over our loopback defaults).")
        @click.option("--namespace", "bus_namespace", default="", metavar="NS",
                      help="Prefix for every key, so several teams can share one network.")
        @functools.wraps(f)
        def wrapper(*args: Any, connect, listen, mode, zenoh_config, bus_namespace, **kwargs: Any):
            opts = BusOptions(mode=mode, connect=list(connect), listen=list(listen),
                              zenoh_config=zenoh_config, namespace=bus_namespace)
            opts.check()  # a bad namespace or config file is bad input: before anything starts
            return f(*args, bus_options=opts, **kwargs)

        return wrapper

    return decorate(f) if f is not None else decorate


class FiniteFloat(click.ParamType):
    """A float option that must be finite (and within bounds): `--duration nan` is bad input."""

    name = "number"

    def __init__(self, min: float | None = None, min_open: bool = False, max: float | None = None):
        self.min, self.min_open, self.max = min, min_open, max

    def convert(self, value, param, ctx):
        if isinstance(value, float):
            x = value
        else:
            try:
                x = float(value)
            except (TypeError, ValueError):
                self.fail(f"{value!r} is not a number", param, ctx)
        if not math.isfinite(x):
            self.fail(f"{value!r} is not a finite number", param, ctx)
        if self.min is not None and (x < self.min or (self.min_open and x == self.min)):
            self.fail(f"{x:g} must be {'>' if self.min_open else '≥'} {self.min:g}", param, ctx)
        if self.max is not None and x > self.max:
            self.fail(f"{x:g} must be ≤ {self.max:g}", param, ctx)
        return x


def finite_float(min: float | None = None, min_open: bool = False,
                 max: float | None = None) -> FiniteFloat:
    return FiniteFloat(min, min_open, max)


class Seed(click.ParamType):
    """A run's master seed: a non-negative 63-bit integer (mrta_zenoh.limits.SEED), as the
    experiment file requires. numpy refuses a negative entropy with a traceback, and a larger
    one would not fit the results' CSV column other tools read as int64."""

    name = "seed"

    def convert(self, value, param, ctx):
        if isinstance(value, int) and not isinstance(value, bool):
            x = value
        else:
            text = str(value).strip()
            if len(text) > 24:  # int() of thousands of digits is refused by Python itself
                self.fail(f"{text[:24]}… {SEED.problem(10**24)}", param, ctx)
            try:
                x = int(text, 10)
            except ValueError:
                self.fail(f"{value!r} is not an integer", param, ctx)
        problem = SEED.problem(x)
        if problem:
            self.fail(problem, param, ctx)
        return x


SEED_TYPE = Seed()


class OutputPath(click.Path):
    """A path the command will write — a folder (`folder=True`) or a file — refused before the
    command starts anything when it cannot be written (mrta_zenoh.files.check_writable): the
    same exit 2 and one line for `--output /proc/x`, `/dev/null/x` or a read-only folder in
    every command."""

    def __init__(self, folder: bool):
        super().__init__(file_okay=not folder, dir_okay=folder, path_type=Path)
        self.folder = folder

    def convert(self, value, param, ctx):
        path = super().convert(value, param, ctx)
        try:
            check_writable(path, folder=self.folder)
        except ConfigError as exc:
            self.fail(str(exc), param, ctx)
        return path


def console(stderr: bool = False) -> "rich.console.Console":
    """A rich Console for a verb's output. On a terminal it draws as usual; into a pipe or a
    file it never wraps (rich would hard-wrap at 80 columns, cutting a line a script greps in
    two) and writes no colour codes."""
    from rich.console import Console

    c = Console(stderr=stderr, highlight=False)
    if not c.is_terminal:
        c.soft_wrap = True
    return c


VERBOSITY_KEY = "mrta.verbosity"


def verbosity() -> int:
    """`-v` minus `-q` on the `mrta` command line (0 outside a click context): -1 (`-q`) means
    no progress output, only the result and errors; -2 (`-qq`) errors only."""
    ctx = click.get_current_context(silent=True)
    return ctx.meta.get(VERBOSITY_KEY, 0) if ctx is not None else 0


LOG_FORMAT = "%(levelname)s %(name)s: %(message)s"
class SafeFormatter(logging.Formatter):
    """Log lines with every unprintable character escaped (`\\x1b`: untrusted.visible, the
    one escape the supervisor's views use too), newlines included: text from the bus (a key, a
    type name, a participant's name) must not reach a terminal raw, where an escape sequence
    could rewrite the screen, and one record is one line, so none can forge another. Only a
    traceback keeps its line breaks (each of its lines is escaped on its own)."""

    def formatMessage(self, record: logging.LogRecord) -> str:
        return visible(super().formatMessage(record))

    def formatException(self, ei) -> str:
        return "\n".join(map(visible, super().formatException(ei).split("\n")))

    def formatStack(self, stack_info: str) -> str:
        return "\n".join(map(visible, super().formatStack(stack_info).split("\n")))


def setup_logging(verbosity: int = 0) -> None:
    """Once per process: `mrta` loggers at INFO (activations, readiness), -v DEBUG, -q WARNING,
    -qq ERROR; other libraries at WARNING; every line through SafeFormatter. The `mrta` group,
    launch-file nodes and missions call this."""
    level = {-2: logging.ERROR, -1: logging.WARNING, 0: logging.INFO}.get(
        max(-2, min(verbosity, 1)), logging.DEBUG)
    root = logging.getLogger()
    if not root.handlers:
        logging.basicConfig(format=LOG_FORMAT, level=logging.WARNING)
        for handler in root.handlers:
            handler.setFormatter(SafeFormatter(LOG_FORMAT))
    logging.getLogger("mrta").setLevel(level)
