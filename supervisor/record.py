"""`mrta record`: every sample (key, time, encoding, payload) into an MCAP file.

One MCAP channel per (key, encoding): topic = the Zenoh key, message encoding `msgpack`, channel
metadata carrying the full Zenoh encoding and the type name, so standard MCAP tools can list and
filter the recording and anyone with msgpack can decode it. Liveliness changes are recorded too,
on topics `@liveliness/<key>` as JSON `{"alive": true|false}`.
"""

from __future__ import annotations

import json
import logging
import queue
import threading
import time
from pathlib import Path

import click
from mcap.writer import Writer

from mrta_zenoh.bus import BusOptions, open_bus
from mrta_zenoh.cli.common import bus_options, user_errors
from mrta_zenoh.codec import DecodeError, type_from_encoding
from mrta_zenoh.errors import ConfigError
from mrta_zenoh.keys import validate_key_expr
from mrta_zenoh.lifecycle import stop_on_signals

log = logging.getLogger("mrta.record")


class McapRecorder:
    """Writes from one thread; bus callbacks only enqueue (they must stay tiny)."""

    def __init__(self, path: Path):
        self.path = path
        self._f = open(path, "wb")
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
        while True:
            item = self._q.get()
            if item is None:
                return
            t, key, enc, payload = item
            self._w.add_message(channel_id=self._channel(key, enc), log_time=t, publish_time=t,
                                data=payload, sequence=self.count)
            self.count += 1

    def close(self) -> None:
        self._q.put(None)
        self._thread.join()
        self._w.finish()
        self._f.close()


def main(output: Path, key_exprs: list[str], bus_opts: BusOptions,
         duration: float | None = None, stop: threading.Event | None = None) -> int:
    with user_errors():
        for k in key_exprs:
            validate_key_expr(k)
        if output.parent and not output.parent.exists():
            raise ConfigError(f"folder {output.parent} does not exist")
    with user_errors(), stop_on_signals(stop) as stop, open_bus(bus_opts) as bus:
        rec = McapRecorder(output)
        subs = [bus.subscribe_raw(k, lambda s: rec.sample(s.key, s.encoding, s.payload))
                for k in key_exprs]
        watch = bus.watch_liveliness("**", rec.liveliness)
        log.info("recording %s to %s", " ".join(key_exprs), output)
        try:
            stop.wait(duration)
        finally:
            for s in subs:
                s.close()
            watch.close()
            rec.close()
    log.info("wrote %d messages to %s", rec.count, output)
    return 0


@click.command()
@click.option("-o", "--output", required=True, type=click.Path(dir_okay=False, path_type=Path),
              help="The MCAP file to write.")
@click.argument("key_exprs", nargs=-1)
@click.option("--duration", type=float, help="Stop after this many seconds.")
@bus_options
def record(output: Path, key_exprs: tuple[str, ...], duration: float | None,
           bus_options: BusOptions) -> None:
    """Record every sample on KEYEXPR… (default: everything) to an MCAP file."""
    logging.getLogger("mrta.record").setLevel(logging.INFO)
    if not logging.getLogger().handlers:
        logging.basicConfig(format="%(levelname)s %(name)s: %(message)s")
    main(output, list(key_exprs) or ["**"], bus_options, duration)
