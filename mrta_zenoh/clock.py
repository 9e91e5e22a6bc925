"""Clocks: wall, simulation (follows the `clock` key) and manual (tests).

Logic takes a clock instead of reading the system time, so the same ALLIANCE code runs in real
time, k× faster under the simulator, and step by step in a unit test.
"""

from __future__ import annotations

import contextlib
import logging
import threading
import time
from typing import Protocol

log = logging.getLogger("mrta.clock")
EPSILON = 1e-9  # simulated times this close are the same instant (sums of 0.02 s steps drift)


class Clock(Protocol):
    def now(self) -> float:
        """Seconds. Wall clock: epoch seconds; simulation: simulated seconds since start."""

    def sleep_until(self, t: float, stop: threading.Event | None = None) -> bool:
        """Block until now() ≥ t; return False if `stop` was set first."""


class WallClock:
    now = staticmethod(time.time)  # a C call: read once per sample on receive paths

    def sleep_until(self, t: float, stop: threading.Event | None = None) -> bool:
        while True:
            remaining = t - time.time()
            if remaining <= 0:
                return True
            if stop is None:
                time.sleep(remaining)
            elif stop.wait(remaining):
                return False


class ManualClock:
    """Time moves only when a test calls advance(); sleepers wake when it passes their target."""

    def __init__(self, start: float = 0.0):
        self._now = start
        self._cond = threading.Condition()

    def now(self) -> float:
        return self._now

    def advance(self, dt: float) -> None:
        self.set(self._now + dt)

    def set(self, t: float) -> None:
        with self._cond:
            self._now = t
            self._cond.notify_all()

    def sleep_until(self, t: float, stop: threading.Event | None = None) -> bool:
        with self._cond:
            while self._now < t:
                if stop is not None and stop.is_set():
                    return False
                self._cond.wait(0.05)
        return True


class SimClock(ManualClock):
    """Simulation time as published on the `clock` key, defended against what a bus can bring.

    Before the first clock sample arrives, now() is 0 and `started` is unset; sleepers wait for the
    simulator (a paused simulator pauses every agent, which is what simulation time means).

    Which samples move time (docs/architecture.md, "the clock"):
      * the first source heard is adopted; samples carry the publishing run's `source` id;
      * from the adopted source, time moves forward by at most `max_jump` simulated seconds per
        sample (a simulator publishes every 20 ms step); a late duplicate is ignored, a larger
        jump (a forged 1e9) is rejected and counted;
      * a sample from another source is adopted as a new run (a restarted simulator) — with a
        log line, time restarting from its stamp — once the adopted source has been silent for
        `silence` wall seconds or its liveliness token is gone; before that it is rejected and
        counted (a second simulator, or a forgery);
      * non-finite stamps never get here: the Clock message rejects them when decoding.
    `stalled(wall_seconds)` tells a follower that time stopped (the simulator died or hangs).
    """

    def __init__(self, max_jump: float = 10.0, silence: float = 2.0, wall=time.monotonic) -> None:
        super().__init__(0.0)
        self.started = threading.Event()
        self.max_jump = max_jump
        self.silence = silence
        self.source: str | None = None
        self.rejected = 0
        self.restarts = 0
        self._wall = wall
        self._last_wall = wall()
        self._source_alive = True

    def on_clock(self, stamp: float, source: str = "") -> bool:
        """Offer a clock sample; True if it moved (or restarted) time."""
        with self._cond:
            now_wall = self._wall()
            if self.source is None:
                self.source = source
            elif source != self.source:
                silent = now_wall - self._last_wall >= self.silence or not self._source_alive
                if not silent:
                    self.rejected += 1
                    return False
                log.warning("clock: new simulation run %r adopted at t=%.3f (was %r at t=%.3f)",
                            source, stamp, self.source, self._now)
                self.source = source
                self.restarts += 1
                self._source_alive = True
                self._now = stamp
                self._last_wall = now_wall
                self._cond.notify_all()
                self.started.set()
                return True
            if stamp < self._now:  # a late duplicate must not move time backwards
                return False
            if self.started.is_set() and stamp - self._now > self.max_jump:
                self.rejected += 1
                return False
            self._now = stamp
            self._last_wall = now_wall
            self._cond.notify_all()
        self.started.set()
        return True

    def sleep_until(self, t: float, stop: threading.Event | None = None) -> bool:
        """Like ManualClock's, but also returns when time restarts (a new simulation run moved
        now() backwards): the caller re-reads now() and reschedules instead of waiting for the
        new run to reach a time of the old one."""
        with self._cond:
            epoch = self.restarts
            while self._now < t - EPSILON and self.restarts == epoch:
                if stop is not None and stop.is_set():
                    return False
                self._cond.wait(0.05)
        return True

    def source_lost(self) -> None:
        """The adopted source's liveliness token is gone: the next run may be adopted at once."""
        with self._cond:
            self._source_alive = False

    def stalled(self, wall_seconds: float) -> bool:
        """No accepted sample for `wall_seconds` of wall time (only meaningful once started)."""
        return self.started.is_set() and self._wall() - self._last_wall >= wall_seconds


def follow_sim_clock(bus, clock: SimClock) -> contextlib.ExitStack:
    """Subscribe `clock` to the bus's `clock` key and watch the clock source's liveliness.

    The one place that makes a process follow the simulator. Returns the subscriptions as one
    resource: use it in a `with` (or enter it in the caller's ExitStack), or close() it."""
    from .keys import CLOCK, CLOCK_SOURCE_TOKEN
    from .messages import Clock as ClockMsg

    def on_token(key: str, alive: bool) -> None:
        if not alive:
            clock.source_lost()

    with contextlib.ExitStack() as handles:  # a failure half-way closes what was opened
        handles.enter_context(bus.subscribe(
            CLOCK, lambda s: clock.on_clock(s.message.stamp, s.message.source),
            msg_type=ClockMsg))
        handles.enter_context(bus.watch_liveliness(CLOCK_SOURCE_TOKEN + "/**", on_token))
        return handles.pop_all()


class Rate:
    """Run a loop at a fixed frequency on any clock, without drift (like rospy.Rate)."""

    def __init__(self, clock: Clock, hz: float):
        if hz <= 0:
            raise ValueError(f"rate must be positive, got {hz}")
        self.clock = clock
        self.period = 1.0 / hz
        self._next = clock.now() + self.period

    def sleep(self, stop: threading.Event | None = None) -> bool:
        ok = self.clock.sleep_until(self._next, stop)
        now = self.clock.now()
        self._next += self.period
        if self._next < now:  # fell behind (or time jumped): resynchronise instead of bursting
            self._next = now + self.period
        return ok
