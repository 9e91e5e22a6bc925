"""Record the bus to MCAP: `mrta record`'s api."""

from __future__ import annotations

import contextlib
import threading
import time
from pathlib import Path

from ..bus import Bus, BusOptions
from ..clock import SimClock
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
    `duration` wall seconds pass or `stop` is set (then, with `sim_time`, until the clock has
    been quiet: `drain`); announce the recorder while it runs.

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
        if sim_time:
            drain(node.clock)
    log.info("wrote %s to %s", plural(rec.count, "message"), output)
    return 0


DRAIN_QUIET = 0.5  # wall s without a clock sample: the recorder has what the simulator sent
DRAIN_MAX = 4.0    # wall s a stopped recorder goes on recording at most (well within RECORDER_GRACE)


def drain(clock: SimClock) -> None:
    """A recorder told to stop goes on recording while clock samples still come, until the
    clock has been quiet for DRAIN_QUIET (at most DRAIN_MAX): a mission runner stops it as soon
    as the simulator has ended, and a recorder behind on a busy machine (20 robots, `--speed
    0`) still had the last simulated second queued — closing then cut the recording short of
    the mission ("the recording does not cover the whole mission"; issue 51, the newcomer's
    `--no-plots` run: with plots, the simulator's snapshot delayed the stop long enough)."""
    deadline = clock.wall() + DRAIN_MAX  # the clock's wall: quiet and bound on one time
    while (clock.started.is_set() and not clock.stalled(DRAIN_QUIET)
           and clock.wall() < deadline):
        time.sleep(0.05)
