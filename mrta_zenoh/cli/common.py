"""What every networked subcommand shares: the bus options and the error → exit-code mapping."""

from __future__ import annotations

import functools
from pathlib import Path
from typing import Any, Callable

import click

from ..bus.options import MODES, BusOptions
from ..errors import ConfigError, MrtaRuntimeError
from ..fieldpath import FieldPathError
from ..keys import KeyError_


class BadInput(click.ClickException):
    """Exit 2 with one line: bad usage, file, parameter or value (DESIGN §9)."""

    exit_code = 2


class RuntimeFailure(click.ClickException):
    exit_code = 1


def bus_options(f: Callable) -> Callable:
    """Add --connect/--listen/--mode/--zenoh-config/--namespace and pass `bus_options=BusOptions`."""

    @click.option("--connect", "connect", multiple=True, metavar="ENDPOINT",
                  help="Zenoh endpoint to connect to (repeatable), e.g. tcp/192.168.1.10:7447.")
    @click.option("--listen", "listen", multiple=True, metavar="ENDPOINT",
                  help="Zenoh endpoint to listen on (repeatable). Default: tcp/127.0.0.1:0.")
    @click.option("--mode", type=click.Choice(MODES[:2]), default="peer", show_default=True,
                  help="Zenoh session mode.")
    @click.option("--zenoh-config", type=click.Path(dir_okay=False, path_type=Path),
                  metavar="FILE.json5", help="Zenoh configuration file (merged over our loopback defaults).")
    @click.option("--namespace", default="", metavar="NS",
                  help="Prefix for every key, so several teams can share one network.")
    @functools.wraps(f)
    def wrapper(*args: Any, connect, listen, mode, zenoh_config, namespace, **kwargs: Any):
        with user_errors():
            opts = BusOptions(mode=mode, connect=list(connect), listen=list(listen),
                              zenoh_config=zenoh_config, namespace=namespace)
            if opts.namespace:
                from ..keys import validate_key_expr
                validate_key_expr(opts.namespace)
            opts.user_config()  # a bad file is bad input: fail before anything starts
        return f(*args, bus_options=opts, **kwargs)

    return wrapper


class user_errors:
    """Context manager turning library errors into click exceptions with the right exit code."""

    def __enter__(self) -> "user_errors":
        return self

    def __exit__(self, exc_type, exc, tb) -> bool:
        if exc is None:
            return False
        if isinstance(exc, (ConfigError, FieldPathError, KeyError_)):
            raise BadInput(str(exc)) from exc
        if isinstance(exc, MrtaRuntimeError):
            raise RuntimeFailure(str(exc)) from exc
        return False
