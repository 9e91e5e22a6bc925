"""Recording the bus to MCAP, and reading a recording back (also one whose end is missing).

One MCAP channel per (key, encoding): topic = the Zenoh key, message encoding `msgpack`, channel
metadata carrying the full Zenoh encoding and the type name, so standard MCAP tools can list and
filter the recording and anyone with msgpack can decode it. Liveliness changes are recorded too,
on topics `@liveliness/<key>` as JSON `{"alive": true|false}`.

Crash safety: the writer closes its chunk and flushes at least once a second, so a recorder
killed with SIGKILL leaves a file whose complete chunks a streaming read recovers; the readers
here fall back to that and say how much they recovered.
"""

from __future__ import annotations

import bisect
import json
import logging
import queue
import threading
import time
from pathlib import Path
from typing import Iterator

from mcap.reader import make_reader
from mcap.records import Channel, Message as McapMessage
from mcap.stream_reader import StreamReader
from mcap.writer import Writer

from . import codec, keys
from .codec import DecodeError, type_from_encoding
from .errors import ConfigError

log = logging.getLogger("mrta.record")

Record = tuple[str, str, int, bytes]  # (key, encoding, log time ns, payload)


class McapRecorder:
    """Writes from one thread; bus callbacks only enqueue (they must stay tiny)."""

    def __init__(self, path: Path, flush_every: float = 1.0):
        self.path = path
        self.flush_every = flush_every
        try:
            self._f = open(path, "wb")
        except OSError as exc:
            raise ConfigError(f"cannot write the recording: {exc.strerror}", file=str(path)) from None
        self._w = Writer(self._f)
        self._w.start(profile="", library="mrta-zenoh")
        self._channels: dict[tuple[str, str], int] = {}
        self._q: queue.SimpleQueue = queue.SimpleQueue()
        self.count = 0
        self._thread = threading.Thread(target=self._run, name="mcap-writer", daemon=True)
        self._thread.start()

    def sample(self, key: str, encoding: str, payload: bytes) -> None:
        self._q.put((time.time_ns(), key, encoding, payload))

    def liveliness(self, key: str, alive: bool) -> None:
        self._q.put((time.time_ns(), f"@liveliness/{key}", "application/json",
                     json.dumps({"alive": alive}).encode()))

    def _channel(self, key: str, encoding: str) -> int:
        ch = self._channels.get((key, encoding))
        if ch is None:
            try:
                type_name = type_from_encoding(encoding)
            except DecodeError:
                type_name = ""  # not our wire format: recorded as is, bytes untouched
            msg_enc = "json" if encoding.startswith("application/json") else "msgpack"
            ch = self._w.register_channel(topic=key, message_encoding=msg_enc, schema_id=0,
                                          metadata={"encoding": encoding, "type": type_name})
            self._channels[(key, encoding)] = ch
        return ch

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
            if item:
                t, key, enc, payload = item
                self._w.add_message(channel_id=self._channel(key, enc), log_time=t, publish_time=t,
                                    data=payload, sequence=self.count)
                self.count += 1
            if time.monotonic() >= next_flush:
                self._w.flush()
                next_flush = time.monotonic() + self.flush_every

    def close(self) -> None:
        self._q.put(None)
        self._thread.join()
        self._w.finish()
        self._f.close()




class Recovered(list):
    """Records read from a file; `complete` is False when its end was missing."""

    complete = True
    note = ""


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
            for _schema, channel, message in reader.iter_messages(log_time_order=True):
                out.append(_row(channel, message))
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
                elif isinstance(rec, McapMessage) and rec.channel_id in channels:
                    out.append(_row(channels[rec.channel_id], rec))
        except Exception as exc:  # noqa: BLE001 - the truncated tail, whatever it looks like
            log.debug("recording %s ends early: %s", path, exc)
    if not out:
        raise ConfigError("not a readable MCAP file (no complete chunk)", file=str(path))
    out.sort(key=lambda r: r[2])
    out.complete = False
    span = (out[-1][2] - out[0][2]) / 1e9
    out.note = (f"{path}: the file's end is missing (was the recorder killed?); recovered "
                f"{len(out)} messages covering {span:.1f} s")
    log.warning("%s", out.note)
    return out


def _row(channel, message) -> Record:
    return (channel.topic, channel.metadata.get("encoding", ""), message.log_time, message.data)


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


