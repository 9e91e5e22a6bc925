"""Samples (or one field of them) as text lines as they arrive, like `rostopic echo`: `mrta echo`'s
api. The verb prints the lines; this module only formats them."""

from __future__ import annotations

import json
import logging
import time
from typing import Any, Callable

import yaml

from .. import codec, jsonsafe
from ..bus import BusOptions, open_bus
from ..fieldpath import FieldPath, FieldPathError
from ..keys import validate_key_expr
from ..lifecycle import stop_on_signals
from ..messages import is_message

log = logging.getLogger("mrta.echo")


def format_sample(key: str, type_name: str, value: Any, as_json: bool, field: FieldPath | None) -> str:
    if as_json:
        out = {"key": key, "type": type_name}
        out["value" if field else "message"] = value
        # JSON has no NaN or Infinity: such a number (only a foreign client can send one, in a
        # type we do not know) is written as its string, so the line stays valid JSON
        return jsonsafe.dumps(out, nonfinite=str, default=_json_default)
    value = jsonsafe.tidy_all(value)  # 51.62, not 51.620000000000005
    if field is not None:
        return f"{key}: {_scalar(value)}"
    body = yaml.safe_dump(value, sort_keys=False, default_flow_style=None).rstrip()
    return f"--- {key} [{type_name}]\n{body}"


def _plain(value: Any) -> Any:
    """Field values may be messages or tuples of messages: make them JSON/YAML friendly."""
    if is_message(value):
        return codec.to_dict(value)
    if isinstance(value, tuple):
        return [_plain(v) for v in value]
    return value


def _scalar(value: Any) -> str:
    if isinstance(value, (dict, list)):
        return json.dumps(value, default=_json_default)
    return str(value)


def _json_default(v: Any) -> Any:
    if isinstance(v, bytes):
        return v.hex()
    raise TypeError(f"not JSON serialisable: {type(v).__name__}")


def run_echo(*, bus_options: BusOptions, key_expr: str, emit: Callable[[str], None],
             warn: Callable[[str], None] = log.warning, field: str | None = None,
             count: int | None = None, as_json: bool = False,
             timeout: float | None = None) -> int:
    """Hand each sample, formatted, to `emit` until `count` were emitted, a signal arrives or
    `timeout` elapses; return how many. What to do with the lines (print them, collect them) is
    the caller's: a library function never prints. `warn` hears of samples it had to skip."""
    validate_key_expr(key_expr)
    path = FieldPath.parse(field) if field else None
    printed = 0

    def on_error(key: str, exc: Exception) -> None:
        warn(f"dropped malformed sample on {key}: {exc}")

    with stop_on_signals() as stop, open_bus(bus_options) as bus:
        sub = bus.subscribe(key_expr, queue_size=1000, on_error=on_error)
        deadline = None if timeout is None else time.monotonic() + timeout
        while not stop.is_set() and (count is None or printed < count):
            if deadline is not None and time.monotonic() > deadline:
                break
            sample = sub.get(timeout=0.1)
            if sample is None:
                continue
            try:
                value = path.resolve(sample.message) if path else sample.message
            except FieldPathError as exc:
                warn(f"{sample.key}: {exc}")
                continue
            emit(format_sample(sample.key, sample.type_name, _plain(value), as_json, path))
            printed += 1
    return printed
