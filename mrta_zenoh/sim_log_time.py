"""Log times in simulated time, for a recorder that follows the simulator's clock
(mrta_zenoh.recording: `mrta record --sim-time`, `mrta view --sim-time`, the mission's
recorder)."""

from __future__ import annotations

import threading
import time

from . import codec, keys
from .clock import SimClock
from .codec import DecodeError
from .messages import Clock

NS = 1_000_000_000
RESTART_GAP_NS = NS  # a restarted simulation's log times start this long after the last run's


class SimLogTime:
    """Log times in simulated time: nanoseconds of `clock` (a SimClock the recorder follows).

    * Before the first clock sample there is no simulated time: the call returns None and the
      recorder holds the sample until the first stamped one, then writes it at that sample's
      log time (the run's first instant). Nothing is stamped with a time it never had, and a
      recorder that joins a run late does not start its file at 0 with a gap up to the present.
    * A restarted simulation (the clock adopted a new run, `SimClock.restarts`) starts again
      from its own stamps; its log times are offset so that they continue RESTART_GAP_NS after
      the last log time handed out. One file, log times increasing throughout, the runs one
      after the other, as readers expect; the `clock` channel still holds each run's own
      stamps, which is what TimeBase maps log times back to.
    * Log times handed out never decrease (a late or concurrent caller gets the latest one).

    `observe` is to be called with every raw sample before stamping it: a `clock` sample moves
    the clock first, so it is logged at its own stamp whichever subscription Zenoh served first.
    """

    def __init__(self, clock: SimClock, dated: bool = False):
        self.clock = clock
        self.dated = dated
        self._lock = threading.Lock()
        self._restarts = clock.restarts
        self._offset = 0
        self._origin: int | None = None if dated else 0
        self._last = 0
        self._decode = None

    def observe(self, key: str, encoding: str, payload: bytes) -> None:
        if key != keys.CLOCK:
            return
        try:
            if self._decode is None or self._decode[0] != encoding:
                self._decode = (encoding, codec.decoder_for(encoding)[1])
            msg = self._decode[1](payload)
        except DecodeError:
            return  # counted by the clock's typed subscriber; it moves nothing here
        if isinstance(msg, Clock):
            self.clock.on_clock(msg.stamp, msg.source)

    def __call__(self) -> int | None:
        clock = self.clock
        if not clock.started.is_set():
            return None
        while True:  # a consistent (restarts, now) pair: a restart changes both
            restarts = clock.restarts
            now = clock.now()
            if clock.restarts == restarts:
                break
        t = round(now * NS)
        with self._lock:
            if self._origin is None:
                self._origin = time.time_ns() - t
            t += self._origin
            if restarts != self._restarts:
                self._restarts = restarts
                self._offset = self._last + RESTART_GAP_NS - t
            out = max(self._last, self._offset + t)
            self._last = out
            return out
