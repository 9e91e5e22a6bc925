"""Recording the bus to MCAP, and reading a recording back (also one whose end is missing).

One MCAP channel per (key, encoding): topic = the Zenoh key, message encoding `msgpack`, channel
metadata carrying the full Zenoh encoding and the type name, so standard MCAP tools can list and
filter the recording and anyone with msgpack can decode it. Liveliness changes are recorded too,
on topics `@liveliness/<key>` as JSON `{"alive": true|false}`.

Log time: wall time (ns since the epoch) by default; in a simulated-time recording
(`SimLogTime`, mrta_zenoh/sim_log_time.py: `mrta view --sim-time`, the mission runner's recorder,
`run_record(sim_time=True)`)
the simulated time of the run as the recorder's `SimClock` follows it, so Foxglove plays a run at
mission speed whatever `--speed` it ran at. Either way a channel's log times never decrease (MCAP
readers expect it). The file's `mrta` metadata record says which (`log_time`: `wall` or
`simulated`).

Crash safety: the writer closes its chunk and flushes at least once a second, so a recorder
killed with SIGKILL leaves a file whose complete chunks a streaming read recovers; the readers
here fall back to that and say how much they recovered.
"""

from __future__ import annotations

import bisect
import json
import logging
import os
import queue
import threading
import time
from pathlib import Path
from typing import Any, Callable

from mcap.reader import make_reader
from mcap.records import Channel, Message as McapMessage, Metadata
from mcap.stream_reader import StreamReader
from mcap.writer import Writer
import msgspec

from . import codec, keys
from .codec import DecodeError, type_from_encoding
from .errors import ConfigError, MrtaRuntimeError
from .flat_schema import from_viewer, message_schema, object_schema, to_viewer
from .lifecycle import Closing
from .messages import message_class
from .sim_log_time import SimLogTime

_json = msgspec.json  # lossless for our values: shortest round-trip floats

log = logging.getLogger("mrta.record")

Record = tuple[str, str, int, bytes]  # (key, encoding, log time ns, payload)


LIVELINESS_SCHEMA = {"title": "liveliness", "type": "object",
                     "properties": {"alive": {"type": "boolean"}}, "required": ["alive"]}
HOLD_MAX = 10_000  # samples held for the first clock sample; beyond, written at log time 0
# channels (keys) one recording holds; keys come from the network, and a flood of invented
# ones must not grow the recorder's memory (and the file's summary) for good: samples on keys
# beyond are counted (`refused`) and not written
MAX_CHANNELS = 20_000


def json_channel(encoding: str) -> tuple[tuple[str, str, bytes], Any] | None:
    """For a sample of our wire format: ((schema name, "jsonschema", schema), payload → JSON
    bytes); None for anything else. What viewers (Foxglove, Lichtblick) decode: the schema is
    flattened to what their parsers take, a header's stamp written as ROS time
    (mrta_zenoh.flat_schema)."""
    try:
        type_name = type_from_encoding(encoding)
    except DecodeError:
        return None
    cls = message_class(type_name)
    schema = message_schema(cls) if cls is not None else \
        json.dumps(object_schema(type_name, "a type this recorder does not know")).encode()
    _, decode = codec.decoder_for(encoding)
    encode = to_viewer(cls) if cls is not None else _json.encode
    return (type_name, "jsonschema", schema), (lambda payload: encode(decode(payload)))


def check_output(path: Path) -> None:
    """ConfigError (exit 2) up front for an output a recorder could not create: its folder
    missing, not a folder, or not writable; the path itself a folder."""
    path = Path(path)
    folder = path.resolve().parent
    if not folder.is_dir():
        raise ConfigError(f"folder {folder} does not exist", file=str(path))
    if path.is_dir():
        raise ConfigError("is a folder, not a file", file=str(path))
    if not os.access(folder, os.W_OK | os.X_OK) or path.exists() and not os.access(path, os.W_OK):
        raise ConfigError(f"cannot write the recording: folder {folder} is not writable"
                          if not os.access(folder, os.W_OK | os.X_OK) else
                          "cannot write the recording: the file is read-only", file=str(path))


class McapRecorder(Closing):
    """Writes from one thread; bus callbacks only enqueue (they must stay tiny).

    Every bus channel is written as Foxglove and Lichtblick read it: JSON messages with a JSON
    Schema generated from the message definition (msgspec, flattened for the viewers' parsers:
    mrta_zenoh.flat_schema), topic = the Zenoh key. The channel
    metadata keeps the Zenoh encoding and type name, and msgspec's JSON is lossless for our
    values, so a recording still replays the bus exactly (read_recording turns it back into the
    wire's msgpack). A sample that is not in our wire format, or malformed, is kept as it came
    (message encoding `msgpack` or the raw one): preserved, though no viewer decodes it.
    Derived channels (a scene, a supervisor's state) are added with `add`.

    A file that cannot be written (a full disk, a file size limit, a vanished mount) calls
    `on_error` once, from the writer thread: `mrta record` and `mrta view` stop then, and
    `close` raises MrtaRuntimeError (exit 1) saying how much was written and lost.

    Log time: `log_time()` when the sample is handed over (its arrival, taken in the caller's
    thread, not when the writer gets to it), for every channel alike: the wall time by default,
    the simulated time with a SimLogTime. A `log_time` returning None means "no time yet": the
    sample is held (up to HOLD_MAX) and written at the first log time that follows. Log times
    are clamped so that a channel's never decrease (arrivals on two threads can swap by a few
    microseconds). Publish time equals log time: the bus carries no send time (a message's own
    header stamp is in its payload).
    """

    def __init__(self, path: Path, flush_every: float = 1.0,
                 log_time: Callable[[], int | None] | None = None,
                 on_error: Callable[[], None] | None = None):
        self.path = path
        self.flush_every = flush_every
        self.log_time = log_time or time.time_ns
        self.simulated = isinstance(log_time, SimLogTime)
        try:
            self._f = open(path, "wb")
        except OSError as exc:
            raise ConfigError(f"cannot write the recording: {exc.strerror}", file=str(path)) from None
        self._w = Writer(self._f)
        self._w.start(profile="", library="mrta-zenoh")
        meta = {"log_time": "simulated" if self.simulated else "wall"}
        if self.simulated and log_time.dated:
            meta["time_origin"] = "run_start"
        self._w.add_metadata("mrta", meta)
        self._channels: dict[tuple[str, str], tuple[int, Any]] = {}
        self._schemas: dict[tuple[str, str], int] = {}
        self._last: dict[int, int] = {}  # channel id → its last log time
        self._held: list[tuple] = []  # samples that came before the first log time
        self._q: queue.SimpleQueue = queue.SimpleQueue()
        self.count = 0
        self.lost = 0  # samples not written because the file could not be (a full disk)
        self.refused = 0  # samples on new keys beyond MAX_CHANNELS
        self._error: OSError | None = None
        self._on_error = on_error
        self._thread = threading.Thread(target=self._run, name="mcap-writer", daemon=True)
        self._thread.start()

    def sample(self, key: str, encoding: str, payload: bytes, t: int | None = None) -> None:
        """A bus sample; `t` (ns) defaults to `log_time()` now."""
        self._q.put((self.log_time() if t is None else t, key, encoding, payload))

    def liveliness(self, key: str, alive: bool, t: int | None = None) -> None:
        self._q.put((self.log_time() if t is None else t, keys.LIVELINESS_PREFIX + key,
                     "application/json", json.dumps({"alive": alive}).encode()))

    def add(self, topic: str, schema: tuple[str, str, bytes], message_encoding: str,
            data: bytes, t: int | None = None) -> None:
        """A derived channel's message: schema = (name, encoding, data)."""
        self._q.put((self.log_time() if t is None else t, topic,
                     ("derived", schema, message_encoding), data))

    def _schema(self, name: str, encoding: str, data: bytes) -> int:
        sid = self._schemas.get((name, encoding))
        if sid is None:
            sid = self._schemas[(name, encoding)] = self._w.register_schema(name, encoding, data)
        return sid

    def _channel(self, key: str, encoding) -> tuple[int, Any] | None:
        """(channel id, payload converter) for a key and its encoding, registered once; None
        for a new bus key beyond MAX_CHANNELS."""
        ident = (key, encoding if isinstance(encoding, str) else encoding[1][0])
        entry = self._channels.get(ident)
        if entry is not None:
            return entry
        if len(self._channels) >= MAX_CHANNELS and isinstance(encoding, str):
            return None  # derived channels (the recorder's own) are never refused
        if not isinstance(encoding, str):  # a derived channel
            _, (name, schema_enc, data), msg_enc = encoding
            ch = self._w.register_channel(topic=key, message_encoding=msg_enc,
                                          schema_id=self._schema(name, schema_enc, data))
            entry = (ch, None)
        elif key.startswith(keys.LIVELINESS_PREFIX):
            sid = self._schema("liveliness", "jsonschema", json.dumps(LIVELINESS_SCHEMA).encode())
            entry = (self._w.register_channel(topic=key, message_encoding="json", schema_id=sid,
                                              metadata={"encoding": encoding, "type": ""}), None)
        else:
            converter = json_channel(encoding)
            if converter is not None:
                (name, schema_enc, data), convert = converter
                ch = self._w.register_channel(topic=key, message_encoding="json",
                                              schema_id=self._schema(name, schema_enc, data),
                                              metadata={"encoding": encoding, "type": name})
                entry = (ch, convert)
            else:  # not our wire format: recorded as is, bytes untouched
                msg_enc = "json" if encoding.startswith("application/json") else "msgpack"
                entry = (self._w.register_channel(topic=key, message_encoding=msg_enc, schema_id=0,
                                                  metadata={"encoding": encoding, "type": ""}),
                         None)
        self._channels[ident] = entry
        return entry

    def _write(self, t: int | None, key: str, enc, payload: bytes) -> None:
        if t is None:  # no log time yet (simulated time not started): held for the next one
            if len(self._held) < HOLD_MAX:
                self._held.append((key, enc, payload))
                return
            t = 0  # a bus with no simulator for long: memory stays bounded
        elif self._held:
            held, self._held = self._held, []
            for item in held:
                self._write(t, *item)
        entry = self._channel(key, enc)
        if entry is None:
            self.refused += 1
            if self.refused == 1:
                log.warning("more than %d keys: samples on new keys are not recorded",
                            MAX_CHANNELS)
            return
        ch, convert = entry
        if convert is not None:
            try:
                payload = convert(payload)
            except DecodeError:  # malformed: kept as it came, on a channel of its own
                entry = self._channel(key + "/@malformed", "application/octet-stream")
                if entry is None:
                    self.refused += 1
                    return
                ch = entry[0]
        t = max(t, self._last.get(ch, 0))
        self._last[ch] = t
        self._w.add_message(channel_id=ch, log_time=t, publish_time=t, data=payload,
                            sequence=self.count)
        self.count += 1

    def _run(self) -> None:
        """Write as samples come; close the chunk and flush the file at least every
        `flush_every` seconds, so a SIGKILL loses at most that much."""
        next_flush = time.monotonic() + self.flush_every
        while True:
            try:
                item = self._q.get(timeout=max(0.0, next_flush - time.monotonic()))
            except queue.Empty:
                item = ()
            if item is None:
                return
            if self._error is not None:  # the file cannot be written: count, keep draining
                self.lost += bool(item)
                continue
            try:
                if item:
                    self._write(*item)
                if time.monotonic() >= next_flush:
                    self._w.flush()
                    next_flush = time.monotonic() + self.flush_every
            except OSError as exc:  # a full disk, a vanished mount: reported once, at close
                self._error = exc
                self.lost += bool(item)
                log.error("cannot write %s: %s; recording stops", self.path,
                          exc.strerror or exc)
                if self._on_error is not None:
                    self._on_error()  # the recorder stops: it exits 1 when it closes this

    def close(self) -> None:
        """Write what is queued, finish the file (its summary and index); once. Samples still
        held (simulated time never started) are written at log time 0."""
        if self._f.closed:
            return
        self._q.put(None)
        self._thread.join()
        held, self._held = self._held, []
        try:
            if self._error is None:
                for item in held:
                    self._write(0, *item)
                self._w.finish()
        except OSError as exc:
            self._error = exc
        finally:
            try:
                self._f.close()
            except OSError as exc:  # the last buffered bytes did not fit either
                self._error = self._error or exc
        if self._error is not None:
            raise MrtaRuntimeError(f"cannot write the recording {self.path}: "
                                   f"{self._error.strerror or self._error} "
                                   f"({self.count} samples written, {self.lost} lost)")


class Recovered(list):
    """Records read from a file; `complete` is False when its end was missing. `log_time`:
    "simulated" or "wall" as the file's `mrta` metadata says ("" for a file without it).
    `memo`: what the analysis derives from the records more than once (the architecture's
    reports of who is doing what, read by the intervals, the stretches and the application's
    metrics alike), kept with the records it was derived from (they are not changed once read)."""

    complete = True
    note = ""
    log_time = ""

    def __init__(self, *args):
        super().__init__(*args)
        self.memo: dict = {}


def read_recording(path: Path) -> Recovered:
    """Every record (key, encoding, log_time_ns, payload) in log-time order.

    A file without its summary (the recorder was killed) is read as a stream up to the last
    complete chunk; `.complete` is then False and `.note` says how much was recovered."""
    try:
        f = open(path, "rb")
    except OSError as exc:
        raise ConfigError(f"cannot read recording: {exc.strerror}", file=str(path)) from None
    out = Recovered()
    with f:
        try:
            reader = make_reader(f)
            # in the file's order, then sorted by log time: ties keep the file's order, which
            # is the order the library's log-time merge gives (log time, then position), at a
            # C sort's cost instead of a heap of Python comparisons (half the reading)
            for _schema, channel, message in reader.iter_messages(log_time_order=False):
                row = _row(channel, message)
                if row is not None:
                    out.append(row)
            out.sort(key=_log_time)
            out.log_time = next((m.metadata.get("log_time", "") for m in reader.iter_metadata()
                                 if m.name == "mrta"), "")
            return out
        except Exception:  # noqa: BLE001 - the mcap library raises many types for a bad end
            pass
        f.seek(0)
        out.clear()
        channels: dict[int, Channel] = {}
        try:  # record by record (chunks unpacked): everything before the cut is usable
            for rec in StreamReader(f).records:
                if isinstance(rec, Channel):
                    channels[rec.id] = rec
                elif isinstance(rec, Metadata) and rec.name == "mrta":
                    out.log_time = rec.metadata.get("log_time", "")
                elif isinstance(rec, McapMessage) and rec.channel_id in channels:
                    row = _row(channels[rec.channel_id], rec)
                    if row is not None:
                        out.append(row)
        except Exception as exc:  # noqa: BLE001 - the truncated tail, whatever it looks like
            log.debug("recording %s ends early: %s", path, exc)
    if not out:
        raise ConfigError("not a readable MCAP file (no complete chunk)", file=str(path))
    out.sort(key=_log_time)
    out.complete = False
    span = (out[-1][2] - out[0][2]) / 1e9
    out.note = (f"{path}: the file's end is missing (was the recorder killed?); recovered "
                f"{len(out)} messages covering {span:.1f} s")
    log.warning("%s", out.note)
    return out


def _log_time(record: Record) -> int:
    return record[2]


def _row(channel, message) -> Record | None:
    """A bus record: (key, Zenoh encoding, log time, wire payload); None for derived channels
    (topics starting with '/'), which are for viewers, not the bus."""
    if channel.topic.startswith("/") or channel.topic.endswith("/@malformed"):
        return None
    encoding = channel.metadata.get("encoding", "")
    data = message.data
    if channel.message_encoding == "json" and channel.metadata.get("type"):
        data = _to_wire(channel.metadata["type"], data)
    return (channel.topic, encoding, message.log_time, data)


def _to_wire(type_name: str, data: bytes) -> bytes:
    """A recorded JSON message back to the msgpack the bus carried (lossless for our values)."""
    cls = message_class(type_name)
    try:
        value = from_viewer(data, cls) if cls is not None else _json.decode(data)
    except (msgspec.ValidationError, msgspec.DecodeError):
        return data  # kept; the decoder downstream reports it
    return codec.encode(value) if cls is not None else codec.encode_struct(value)


class TimeBase:
    """log time (ns) → seconds: simulated when a `clock` was recorded, else wall since start."""

    def __init__(self, records: list[tuple[str, str, int, bytes]]):
        self.logs: list[int] = []
        self.stamps: list[float] = []
        for key, enc, t, payload in records:
            if key == keys.CLOCK:
                try:
                    stamp = codec.decode(type_from_encoding(enc), payload).stamp
                except (DecodeError, AttributeError):
                    continue
                self.logs.append(t)
                self.stamps.append(stamp)
        self.t0 = records[0][2] if records else 0
        self.simulated = bool(self.logs)

    def __call__(self, t: int) -> float:
        if not self.simulated:
            return (t - self.t0) / 1e9
        i = bisect.bisect_right(self.logs, t) - 1
        return self.stamps[max(i, 0)]

    @property
    def label(self) -> str:
        return "simulated time (s)" if self.simulated else "time (s)"


