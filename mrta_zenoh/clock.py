"""Clocks: wall, simulation (follows the `clock` key) and manual (tests).

Logic takes a clock instead of reading the system time, so the same ALLIANCE code runs in real
time, k× faster under the simulator, and step by step in a unit test.
"""

from __future__ import annotations

import threading
import time
from typing import Protocol


class Clock(Protocol):
    def now(self) -> float:
        """Seconds. Wall clock: epoch seconds; simulation: simulated seconds since start."""

    def sleep_until(self, t: float, stop: threading.Event | None = None) -> bool:
        """Block until now() ≥ t; return False if `stop` was set first."""


class WallClock:
    def now(self) -> float:
        return time.time()

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
    """Simulation time as last published on the `clock` key.

    Before the first clock sample arrives, now() is 0 and `started` is unset; sleepers wait for the
    simulator (a paused simulator pauses every agent, which is what simulation time means).
    """

    def __init__(self) -> None:
        super().__init__(0.0)
        self.started = threading.Event()

    def on_clock(self, stamp: float) -> None:
        if stamp >= self._now:  # a late duplicate must not move time backwards
            self.set(stamp)
        self.started.set()


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
