"""Samples (or one field of them) as text lines as they arrive, like `rostopic echo`: `mrta echo`'s
api. The verb prints the lines; this module formats them and says what it could not print.

Keeping up: the network thread only queues each raw sample (a bounded queue of MAX_PENDING);
this thread decodes, formats (mrta_zenoh.tools.sample_text) and hands over whatever has queued,
many samples per write: decoding on the network thread and feeding yaml.safe_dump one sample
at a time, a replay at full speed printed one sample in six — silently. What a burst beyond
the queue costs is said: the samples dropped, once a second while it lasts and in all at the
end (benchmarks/echo.py measures echo beside `mrta record`).
"""

from __future__ import annotations

import collections
import contextlib
import json
import logging
import threading
import time
from typing import Any, Callable

from .. import codec, jsonsafe
from ..bus import Bus, BusOptions, open_bus
from ..fieldpath import FieldPath, FieldPathError
from ..keys import validate_key_expr
from ..lifecycle import stop_on_signals
from ..messages import GenericMessage, is_message
from .sample_text import json_text, yaml_text

log = logging.getLogger("mrta.echo")

MAX_PENDING = 100_000  # raw samples queued for printing (≈ 30 MB of sonar clouds)
BATCH = 1_000          # samples formatted per write
REPORT_EVERY = 1.0     # s: how often drops are said while they go on


def format_sample(key: str, type_name: str, value: Any, as_json: bool, field: FieldPath | None) -> str:
    if as_json:
        out = {"key": key, "type": type_name}
        out["value" if field else "message"] = value
        # JSON has no NaN or Infinity: such a number (only a foreign client can send one, in a
        # type we do not know) is written as its string, so the line stays valid JSON
        return json_text(out, default=_json_default)
    if field is not None:
        return f"{key}: {_scalar(jsonsafe.tidy_all(value))}"  # 51.62, not 51.620000000000005
    return f"--- {key} [{type_name}]\n{yaml_text(value)}"


# --------------------------------------------------------------------------- the loop
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


class _Pending:
    """Raw samples from the network thread, bounded: past MAX_PENDING the oldest go (as a ROS
    queue does) and are counted."""

    def __init__(self, limit: int):
        self.queue: collections.deque = collections.deque(maxlen=limit)
        self.cond = threading.Condition()
        self.received = 0
        self.dropped = 0

    def put(self, sample) -> None:  # the network thread: keep it tiny
        with self.cond:
            self.received += 1
            if len(self.queue) == self.queue.maxlen:
                self.dropped += 1
            self.queue.append(sample)
            self.cond.notify()

    def take(self, most: int, timeout: float) -> list:
        with self.cond:
            if not self.queue:
                self.cond.wait(timeout)
            n = min(most, len(self.queue))
            return [self.queue.popleft() for _ in range(n)]


def run_echo(*, bus_options: BusOptions, key_expr: str, emit: Callable[[str], None],
             warn: Callable[[str], None] = log.warning, field: str | None = None,
             count: int | None = None, as_json: bool = False,
             timeout: float | None = None, stop: threading.Event | None = None,
             bus: Bus | None = None) -> int:
    """Hand the samples, formatted, to `emit` (one or more lines a call) until `count` were
    emitted, a signal arrives, `stop` is set or `timeout` elapses; return how many. What to do
    with the lines (print them, collect them) is the caller's: a library function never prints.
    `warn` hears of samples it had to skip: malformed ones, those dropped because `emit` could
    not keep up (at most once a REPORT_EVERY while it lasts, and in all at the end), and those
    a stop left unprinted. `bus`: an open bus to use instead of opening one from `bus_options`
    (tests: the in-process bus); it is left open."""
    validate_key_expr(key_expr)
    path = FieldPath.parse(field) if field else None
    printed = 0
    pending = _Pending(MAX_PENDING)
    decoders: dict[str, tuple] = {}
    said = (0, time.monotonic())  # drops already reported, and when

    def decode(s) -> Any:
        """The sample's (type name, message); None, with a warning, for a malformed one."""
        entry = decoders.get(s.encoding)
        try:
            if entry is None:
                entry = codec.decoder_for(s.encoding)
                if len(decoders) < 64:  # encodings come from the network: bounded
                    decoders[s.encoding] = entry
            return entry[0], entry[1](s.payload)
        except codec.DecodeError as exc:
            warn(f"dropped malformed sample on {s.key}: {exc}")
            return None

    checked: set[type] = set()  # message classes the field path was checked against
    warned: set[str] = set()

    def line(s) -> str | None:
        decoded = decode(s)
        if decoded is None:
            return None
        type_name, message = decoded
        if path is not None and type(message) is not GenericMessage \
                and type(message) not in checked:
            # a field a type has not is not there in any of its samples: a usage error (exit
            # 2), not a warning per sample while `--count` is never reached (issue 51)
            try:
                path.validate(type(message))
            except FieldPathError as exc:
                raise FieldPathError(f"{s.key} carries {type_name}: {exc}") from None
            checked.add(type(message))
        try:
            value = path.resolve(message) if path else message
        except FieldPathError as exc:  # this sample's value (a short list, a generic message)
            text = f"{s.key}: {exc}"
            if text not in warned and len(warned) < 64:  # once each, not once a sample
                warned.add(text)
                warn(text)
            return None
        return format_sample(s.key, type_name, _plain(value), as_json, path)

    with stop_on_signals(stop) as stop, \
            (contextlib.nullcontext(bus) if bus is not None else open_bus(bus_options)) as bus, \
            bus.subscribe_raw(key_expr, pending.put):
        deadline = None if timeout is None else time.monotonic() + timeout
        while not stop.is_set() and (count is None or printed < count):
            if deadline is not None and time.monotonic() > deadline:
                break
            most = BATCH if count is None else min(BATCH, count - printed)
            out = [text for text in map(line, pending.take(most, 0.1)) if text is not None]
            if out:
                emit("\n".join(out))
                printed += len(out)
            now = time.monotonic()
            if pending.dropped > said[0] and now - said[1] >= REPORT_EVERY:
                warn(f"dropped {pending.dropped - said[0]:,} samples in the last "
                     f"{now - said[1]:.0f} s: printing could not keep up "
                     f"({pending.dropped:,} of {pending.received:,} dropped so far)")
                said = (pending.dropped, now)
    if pending.dropped:
        warn(f"dropped {pending.dropped:,} of {pending.received:,} samples in all: printing "
             "could not keep up")
    if pending.queue and (count is None or printed < count):
        warn(f"{len(pending.queue):,} samples received were not printed: stopped before them")
    return printed
