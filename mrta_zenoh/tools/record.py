"""Record the bus to MCAP: `mrta record`'s api."""

from __future__ import annotations

import contextlib
import threading
from pathlib import Path

from ..bus import Bus, BusOptions
from ..errors import ConfigError
from ..identity import OBSERVER
from ..keys import RECORDER_TOKEN, validate_key_expr
from ..lifecycle import wait_for_stop
from ..node import Node, NodeTime
from ..recording import McapRecorder, SimLogTime, check_output, log
from ..yamlfile import plural


def run_record(*, output: Path, key_exprs: list[str], bus_options: BusOptions,
               duration: float | None = None, stop: threading.Event | None = None,
               sim_time: bool = False, dated: bool = False, bus: Bus | None = None) -> int:
    """Write every sample on `key_exprs` (and every liveliness change) to `output` until
    `duration` wall seconds pass or `stop` is set; announce the recorder while it runs.

    Log times are wall time; with `sim_time`, the simulator's time as this recorder follows it
    (mrta_zenoh.recording.SimLogTime: what `mrta view --sim-time` records too), so the file
    plays at mission speed whatever speed the run had; `dated`: from the wall-clock instant the
    run's clock was first heard (SimLogTime). `bus`: an open bus to use instead of opening one
    from `bus_options` (tests: the in-process bus); it is left open.

    A file that cannot be written (a full disk, a file size limit) stops the recorder at once
    and raises MrtaRuntimeError (exit 1) once what can be is closed: a recorder that records
    nothing must not look alive."""
    for k in key_exprs:
        validate_key_expr(k)
    check_output(Path(output))
    if dated and not sim_time:
        raise ConfigError("--dated is for --sim-time (wall-time log times are dates already)")
    # the identity first (Node), then the file: an output that cannot be written is refused
    # before a session opens; closed last (ExitStack order reversed): the token (no longer a
    # recorder), the subscriptions, the session, then the file, finished with everything that
    # arrived
    node = Node(bus_options, OBSERVER, time=NodeTime.SIM if sim_time else NodeTime.WALL,
                stop=stop, bus=bus)
    stamper = SimLogTime(node.clock, dated=dated) if sim_time else None
    with McapRecorder(output, log_time=stamper, on_error=node.stop.set) as rec, node, \
            contextlib.ExitStack() as handles:
        bus, stop = node.bus, node.stop
        if stamper is not None:
            def on_raw(s) -> None:
                stamper.observe(s.key, s.encoding, s.payload)  # a clock sample: its own stamp
                rec.sample(s.key, s.encoding, s.payload)
        else:
            def on_raw(s) -> None:
                rec.sample(s.key, s.encoding, s.payload)
        for k in key_exprs:
            handles.enter_context(bus.subscribe_raw(k, on_raw))
        handles.enter_context(bus.watch_liveliness("**", rec.liveliness))
        handles.enter_context(bus.declare_token(f"{RECORDER_TOKEN}/{bus.zid}"))
        log.info("recording %s to %s", " ".join(key_exprs), output)
        wait_for_stop(stop, duration)
    log.info("wrote %s to %s", plural(rec.count, "message"), output)
    return 0
