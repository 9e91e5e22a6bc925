"""`mrta view`: the bus, the scene and the supervisor, served live to Foxglove / Lichtblick over
the Foxglove WebSocket protocol (foxglove-sdk's server, loopback by default) and/or written to
an MCAP file with the same channels (supervisor/foxglove.py lists them)."""

from __future__ import annotations

import contextlib
import logging
import threading
import time
from pathlib import Path

import foxglove

from mrta_zenoh.bus import BusOptions, open_bus
from mrta_zenoh.clock import SimClock, WallClock, follow_sim_clock
from mrta_zenoh.codec import DecodeError
from mrta_zenoh.errors import ConfigError
from mrta_zenoh.keys import RECORDER_TOKEN
from mrta_zenoh.lifecycle import stop_on_signals
from mrta_zenoh.recording import McapRecorder, json_channel

from .api import Refresh, attach, resolve_application
from .foxglove import FoxgloveOutputs
from .state import Supervisor

log = logging.getLogger("mrta.view")
SCENE_KEYS = ("world", "*/ground_truth", "*/sonar")


class LiveChannels:
    """foxglove-sdk channels, one per topic, on one context served by one WebSocket server."""

    def __init__(self, host: str, port: int):
        self.context = foxglove.Context()
        self.server = foxglove.start_server(name="mrta-zenoh", host=host, port=port,
                                            context=self.context)
        self.host = host
        self.channels: dict[str, foxglove.Channel] = {}
        self._lock = threading.Lock()

    @property
    def url(self) -> str:
        return f"ws://{self.host}:{self.server.port}"

    def emit(self, topic: str, schema: tuple[str, str, bytes], encoding: str, data: bytes,
             t_ns: int) -> None:
        with self._lock:
            ch = self.channels.get(topic)
            if ch is None:
                name, schema_enc, schema_data = schema
                ch = self.channels[topic] = foxglove.Channel(
                    topic, schema=foxglove.Schema(name=name, encoding=schema_enc, data=schema_data),
                    message_encoding=encoding, context=self.context)
        ch.log(data, log_time=t_ns)

    def close(self) -> None:
        self.server.stop()

    def __enter__(self) -> "LiveChannels":
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def run_view(*, app: str | None, bus_options: BusOptions, port: int | None = 8765,
             host: str = "127.0.0.1", output: Path | None = None, sim_time: bool = False,
             rate: float = 4.0, duration: float | None = None,
             stop: threading.Event | None = None, on_ready=None) -> int:
    if port is None and output is None:
        raise ConfigError("nothing to do: give a --port to serve, an --output to record, or both")
    if output is not None and not Path(output).resolve().parent.is_dir():
        raise ConfigError(f"folder {Path(output).parent} does not exist", file=str(output))
    application = resolve_application(app) if app else None
    clock = SimClock() if sim_time else WallClock()
    with stop_on_signals(stop) as stop, open_bus(bus_options) as bus, \
            contextlib.ExitStack() as handles:
        # closed in reverse order: subscriptions and tokens, then the recording and the server
        live = handles.enter_context(LiveChannels(host, port)) if port is not None else None
        recorder = handles.enter_context(McapRecorder(Path(output))) \
            if output is not None else None
        sinks = [s for s in (live.emit if live else None, recorder.add if recorder else None)
                 if s is not None]

        def emit(topic, schema, enc, data, t_ns):
            for sink in sinks:
                sink(topic, schema, enc, data, t_ns)

        outputs = FoxgloveOutputs(emit)
        converters: dict[str, object] = {}

        def on_raw(sample) -> None:
            t = time.time_ns()
            if recorder is not None:
                recorder.sample(sample.key, sample.encoding, sample.payload, t)
            if live is not None:
                conv = converters.get(sample.encoding)
                if conv is None and len(converters) < 256:
                    conv = converters[sample.encoding] = json_channel(sample.encoding) or False
                if conv:
                    schema, convert = conv
                    try:
                        live.emit(sample.key, schema, "json", convert(sample.payload), t)
                    except DecodeError:
                        pass  # counted by the bus's typed subscribers; nothing to show

        if sim_time:
            handles.enter_context(follow_sim_clock(bus, clock))
        handles.enter_context(bus.subscribe_raw("**", on_raw))
        if recorder is not None:
            handles.enter_context(bus.watch_liveliness("**", recorder.liveliness))
        for expr in SCENE_KEYS:
            handles.enter_context(bus.subscribe(
                expr, lambda s: outputs.on_sample(s.key, s.message), queue_size=100))
        sup = refresh = None
        if application is not None:
            app_model, arch = application
            sup = Supervisor(arch, app_model, clock.now())
            for h in attach(sup, bus, clock):
                handles.callback(h.close)
            refresh = Refresh(sup, clock, sim_time)
        if recorder is not None:
            handles.enter_context(bus.declare_token(f"{RECORDER_TOKEN}/{bus.zid}"))
        if live is not None:
            log.info("Foxglove: open a connection to %s", live.url)
        if on_ready is not None:
            on_ready(live.url if live is not None else None)
        start = time.monotonic()
        while not stop.wait(1.0 / rate):
            outputs.frame(time.time_ns(), sup.snapshot(refresh()) if sup is not None else None)
            if duration is not None and time.monotonic() - start >= duration:
                break
    return 0
