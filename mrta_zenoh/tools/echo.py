"""Print samples (or one field of them) as they arrive, like `rostopic echo`: `mrta echo`'s api."""

from __future__ import annotations

import json
import sys
import time
from typing import Any

import yaml

from .. import codec, jsonsafe
from ..bus import BusOptions, open_bus
from ..fieldpath import FieldPath, FieldPathError
from ..keys import validate_key_expr
from ..lifecycle import stop_on_signals
from ..messages import is_message


def format_sample(key: str, type_name: str, value: Any, as_json: bool, field: FieldPath | None) -> str:
    if as_json:
        out = {"key": key, "type": type_name}
        out["value" if field else "message"] = value
        # JSON has no NaN or Infinity: such a number (only a foreign client can send one, in a
        # type we do not know) is written as its string, so the line stays valid JSON
        return jsonsafe.dumps(out, nonfinite=str, default=_json_default)
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


def run_echo(*, bus_options: BusOptions, key_expr: str, field: str | None = None,
             count: int | None = None, as_json: bool = False, out=None, err=None,
             timeout: float | None = None) -> int:
    """Print samples until `count` were printed, a signal arrives or `timeout` elapses."""
    out = out or sys.stdout
    err = err or sys.stderr
    validate_key_expr(key_expr)
    path = FieldPath.parse(field) if field else None
    printed = 0

    def on_error(key: str, exc: Exception) -> None:
        print(f"warning: dropped malformed sample on {key}: {exc}", file=err, flush=True)

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
                print(f"warning: {sample.key}: {exc}", file=err, flush=True)
                continue
            print(format_sample(sample.key, sample.type_name, _plain(value), as_json, path),
                  file=out, flush=True)
            printed += 1
    return printed


