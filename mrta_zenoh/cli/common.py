"""What every subcommand shares: the bus options, logging, checked numbers, and the one mapping
of the library's errors to exit codes (click's style: bad input 2, a runtime failure 1)."""

from __future__ import annotations

import functools
import logging
import math
from pathlib import Path
from typing import Any, Callable

import click

from ..bus.options import MODES, BusOptions
from ..errors import ConfigError, Interrupted, MrtaRuntimeError
from ..fieldpath import FieldPathError
from ..keys import KeyExprError, validate_key_expr


class BadInput(click.ClickException):
    """Exit 2 with one line: bad usage, file, parameter or value (docs/architecture.md, "exit codes")."""

    exit_code = 2


class RuntimeFailure(click.ClickException):
    exit_code = 1


def bus_options(f: Callable | None = None, *, namespace_option: str = "--namespace") -> Callable:
    """Add --connect/--listen/--mode/--zenoh-config/--namespace and pass `bus_options=BusOptions`.

    `namespace_option` renames --namespace for a command that needs the name for something else
    (`mrta ros2 bridge --namespace` is the robot's ROS 2 namespace)."""

    def decorate(f: Callable) -> Callable:
        @click.option("--connect", "connect", multiple=True, metavar="ENDPOINT",
                      help="Zenoh endpoint to connect to (repeatable), e.g. tcp/192.168.1.10:7447.")
        @click.option("--listen", "listen", multiple=True, metavar="ENDPOINT",
                      help="Zenoh endpoint to listen on (repeatable). Default: tcp/127.0.0.1:0.")
        @click.option("--mode", type=click.Choice(MODES[:2]), default="peer", show_default=True,
                      help="Zenoh session mode.")
        @click.option("--zenoh-config", type=click.Path(dir_okay=False, path_type=Path),
                      metavar="FILE.json5",
                      help="Zenoh configuration file (merged over our loopback defaults).")
        @click.option(namespace_option, "bus_namespace", default="", metavar="NS",
                      help="Prefix for every key, so several teams can share one network.")
        @functools.wraps(f)
        def wrapper(*args: Any, connect, listen, mode, zenoh_config, bus_namespace, **kwargs: Any):
            with user_errors():
                opts = BusOptions(mode=mode, connect=list(connect), listen=list(listen),
                                  zenoh_config=zenoh_config, namespace=bus_namespace)
                if opts.namespace:
                    validate_key_expr(opts.namespace)
                opts.user_config()  # a bad file is bad input: fail before anything starts
            return f(*args, bus_options=opts, **kwargs)

        return wrapper

    return decorate(f) if f is not None else decorate


class user_errors:
    """Context manager turning library errors into click exceptions with the right exit code."""

    def __enter__(self) -> "user_errors":
        return self

    def __exit__(self, exc_type, exc, tb) -> bool:
        if exc is None:
            return False
        if isinstance(exc, (ConfigError, FieldPathError, KeyExprError)):
            raise BadInput(str(exc)) from exc
        if isinstance(exc, MrtaRuntimeError):
            raise RuntimeFailure(str(exc)) from exc
        if isinstance(exc, Interrupted):
            raise click.Abort() from exc
        return False


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


LOG_FORMAT = "%(levelname)s %(name)s: %(message)s"


def setup_logging(verbosity: int = 0) -> None:
    """Once per process: `mrta` loggers at INFO (activations, readiness), -v DEBUG, -q WARNING,
    -qq ERROR; other libraries at WARNING. The `mrta` group and run_node both call this."""
    level = {-2: logging.ERROR, -1: logging.WARNING, 0: logging.INFO}.get(
        max(-2, min(verbosity, 1)), logging.DEBUG)
    root = logging.getLogger()
    if not root.handlers:
        logging.basicConfig(format=LOG_FORMAT, level=logging.WARNING)
    logging.getLogger("mrta").setLevel(level)
