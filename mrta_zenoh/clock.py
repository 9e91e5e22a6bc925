"""Clocks: wall, simulation (follows the `clock` key) and manual (tests).

Logic takes a clock instead of reading the system time, so the same ALLIANCE code runs in real
time, k× faster under the simulator, and step by step in a unit test.
"""

from __future__ import annotations

import contextlib
import logging
import math
import os
import threading
import time

from .keys import CLOCK_SOURCE_ENDED
from .untrusted import visible

log = logging.getLogger("mrta.clock")
EPSILON = 1e-9  # simulated times this close are the same instant (sums of 0.02 s steps drift)
# The creep bound (SimClock): simulated seconds per wall second a run may advance, at most its
# announced speed × RATE_MARGIN (a simulator that fell behind its schedule catches up in bursts),
# and CEILING for a run at speed 0 ("as fast as possible") or one that announces no speed. The
# simulator never runs faster than CEILING (simulator/node.py), so no follower lags behind it.
RATE_MARGIN = 1.5
CEILING = 1000.0
MAX_RIVALS = 64  # a flood of forged source tokens costs a bounded amount of memory


class Clock:
    """What logic may ask of time, whatever keeps it. A base class with defaults (py_trees'
    `Behaviour` style): a capability is asked (`in_lockstep()`, `restarts`), never probed for,
    so a clock that lacks one answers with the default instead of a typo silently disabling it."""

    # how often time restarted (a new simulation run moved now() backwards): a loop that sees it
    # change starts afresh. Wall and manual time never restart.
    restarts: int = 0

    def now(self) -> float:
        """Seconds. Wall clock: epoch seconds; simulation: simulated seconds since start."""
        raise NotImplementedError

    def sleep_until(self, t: float, stop: threading.Event | None = None) -> bool:
        """Block until now() ≥ t; return False if `stop` was set first."""
        raise NotImplementedError

    def in_lockstep(self) -> bool:
        """Whether time moves in lockstep now (mrta_zenoh.lockstep): every participant shares
        one simulated time, so a message counts as heard at its own stamp."""
        return False


class WallClock(Clock):
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


class ManualClock(Clock):
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

    Which samples move time (docs/architecture.md, "the clock"; docs/security.md for the threat
    model). Exact checks (hold against anybody who cannot declare tokens, i.e. on a secured fleet,
    and against blind forgers on an open one):
      * once the clock follows the sources' liveliness (`follow_sim_clock`), a run that holds
        `@mrta/clock_source/<run>` is preferred to any run that does not: a sample naming a run
        without a live token moves time only while no run holds one (ROS-style publishers and
        `mrta replay --clock` declare none);
      * the adopted run keeps the clock while its token lives and it speaks; another run with a
        token is a second claimant: its samples are rejected and counted, and it is reported once
        (`rivals`, a log line) — one source per run;
      * non-finite stamps never get here: the Clock message rejects them when decoding;
      * a late duplicate (a stamp behind now) is ignored.
    Heuristic (an attacker on an open bus who copies the run id and declares its token):
      * creep is bounded by wall time: a run that announces its speed in its id (`run_id`, as
        the simulator's do) moves time at most `rate` simulated seconds per wall second (its
        speed × RATE_MARGIN, `CEILING` at speed 0 — the simulator never runs faster), plus a
        burst of `max_jump` seconds; a sample beyond that budget is rejected and counted. After
        a long wall gap (this process was stopped) the budget is what the gap allows, so a
        resumed follower catches up at once. A run that announces no speed, or (when tokens are
        followed) holds no token — a replay keeps the recorded run ids at its own speed —
        moves time by at most `max_jump` per sample.
    A new run is adopted (a restarted simulator) — with a log line, time restarting from its
    stamp — once the adopted run has been silent for `silence` wall seconds or its token is gone.
    `stalled(wall_seconds)` tells a follower that time stopped (the simulator hangs), `ended()`
    that the run is over (its source's token is gone: the simulator or a replay exited).
    """

    def __init__(self, max_jump: float = 10.0, silence: float = 2.0, wall=time.monotonic) -> None:
        super().__init__(0.0)
        self.started = threading.Event()
        self.max_jump = max_jump
        self.silence = silence
        self.source: str | None = None
        self.rejected = 0
        self.restarts = 0
        self.rivals: set[str] = set()
        self._wall = wall
        self._last_wall = wall()
        self._source_alive = True
        self._tracking = False          # follow_sim_clock reports the sources' tokens
        self._live: set[str] = set()    # runs whose @mrta/clock_source/<run> token lives
        self._announced: set[str] = set()  # runs whose source announced their end
        self._rate: float | None = None
        self._budget = max_jump
        self._budget_wall = self._last_wall

    def on_clock(self, stamp: float, source: str = "") -> bool:
        """Offer a clock sample; True if it moved (or restarted) time."""
        with self._cond:
            now_wall = self._wall()
            if source != self.source:
                if not self._may_adopt(source, now_wall):
                    self.rejected += 1
                    return False
                if self.source is not None:
                    log.warning("clock: new simulation run %r adopted at t=%.3f (was %r at "
                                "t=%.3f)", source, stamp, self.source, self._now)
                    self.restarts += 1
                    self._now = stamp
                first = self.source is None
                self.source = source
                self._source_alive = True
                self._rate = run_rate(source)
                self._budget, self._budget_wall = self.max_jump, now_wall
                if not first:
                    self._last_wall = now_wall
                    self._cond.notify_all()
                    self.started.set()
                    return True
            elif stamp < self._now:  # a late duplicate must not move time backwards
                return False
            if self.started.is_set() and not self._spend(stamp - self._now, now_wall):
                self.rejected += 1
                return False
            self._now = stamp
            self._last_wall = now_wall
            self._cond.notify_all()
        self.started.set()
        return True

    def _may_adopt(self, source: str, now_wall: float) -> bool:
        """May `source` replace the adopted run (or be the first)? Under self._cond."""
        if self._tracking and source not in self._live and self._live:
            return False  # a run holds a token: a run without one never moves time
        if self.source is None:
            return True
        held = self._tracking and self.source in self._live
        silent = now_wall - self._last_wall >= self.silence or not self._source_alive
        if self._tracking and source in self._live and self.source in self._live and not silent:
            self._rival(source)
        if self._tracking and source in self._live and not held:
            return True   # a token holder takes over from a run that has none (or lost it)
        return silent

    def _spend(self, jump: float, now_wall: float) -> bool:
        """The creep bound (a token bucket in simulated seconds, refilled with wall time). A
        wall gap refills more than the burst: a follower that was stopped catches up at once."""
        rate = self._rate
        if self._tracking and self.source not in self._live:
            rate = None  # a run without a token (`mrta replay --clock` keeps the recorded ids)
        if rate is None:
            return jump <= self.max_jump
        refill = rate * max(0.0, now_wall - self._budget_wall)
        self._budget_wall = now_wall
        self._budget = min(self._budget + refill, max(self.max_jump, refill))
        if jump > self._budget + EPSILON:
            return False  # what was earned stays; the sample does not spend it
        self._budget -= jump
        return True

    def _rival(self, source: str) -> None:
        if source not in self.rivals and len(self.rivals) < MAX_RIVALS:
            self.rivals.add(source)
            log.warning("clock: a second clock source %r holds a token while %r runs: two "
                        "simulators (or a forger) on one bus; %r is ignored",
                        visible(source, 80), visible(self.source or "", 80), visible(source, 80))

    def on_source(self, run: str, alive: bool) -> None:
        """A clock source's token appeared or vanished (follow_sim_clock); `<run>/ended`: that
        run's source announced its end."""
        run, _, suffix = run.partition("/")
        with self._cond:
            if suffix:
                if suffix == CLOCK_SOURCE_ENDED and alive and len(self._announced) < MAX_RIVALS:
                    self._announced.add(run)
                return
            self._tracking = True
            if alive:
                if len(self._live) < MAX_RIVALS:
                    self._live.add(run)
                if self.source is not None and run != self.source and self.source in self._live:
                    self._rival(run)
            else:
                self._live.discard(run)
                if run == self.source:
                    self._source_alive = False

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

    def source_lost(self, run: str | None = None) -> None:
        """The adopted source's liveliness token is gone: the next run may be adopted at once.
        With `run`, only if that is the adopted one (follow_sim_clock names it)."""
        if run is not None:
            self.on_source(run, False)
            return
        with self._cond:
            self._source_alive = False

    def ended(self) -> bool:
        """The adopted run is over: its source announced the end (`<run>/ended`) and its
        `@mrta/clock_source/<run>` token is gone (the simulator finished, a replay played its
        last sample), and no other run was adopted since. A source whose token went without
        the announcement died (`lost`): that is a fault, not an end. A run that never held a
        token (a ROS-style publisher) never ends this way: it may only pause."""
        with self._cond:
            return (self.started.is_set() and not self._source_alive
                    and self.source in self._announced)

    def wall(self) -> float:
        """The wall time this clock counts silences in (time.monotonic, or a test's hand-moved
        one): a follower that waits for the clock to go quiet bounds its wait on it too."""
        return self._wall()

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
        clock.on_source(key[len(CLOCK_SOURCE_TOKEN) + 1:], alive)

    with contextlib.ExitStack() as handles:  # a failure half-way closes what was opened
        handles.enter_context(bus.subscribe(
            CLOCK, lambda s: clock.on_clock(s.message.stamp, s.message.source),
            msg_type=ClockMsg))
        handles.enter_context(bus.watch_liveliness(CLOCK_SOURCE_TOKEN + "/**", on_token))
        return handles.pop_all()


def run_id(speed: float) -> str:
    """A new run's id: random, and the speed it runs at (`<12 hex>-x<speed>`), which followers
    read to bound how fast its time may move (SimClock). One key chunk."""
    return f"{os.urandom(6).hex()}-x{speed:g}"


def run_speed(run: str) -> float | None:
    """The speed a run id announces (0: as fast as possible); None when it announces none."""
    head, sep, tail = run.rpartition("-x")
    if not sep or not head:
        return None
    try:
        speed = float(tail)
    except ValueError:
        return None
    return speed if math.isfinite(speed) and speed >= 0 else None


def run_rate(run: str) -> float | None:
    """The most simulated seconds per wall second a run's time may move (the creep bound); None
    for a run that announces no speed (a ROS-style publisher, a hand-fed clock): only the
    per-sample `max_jump` holds it."""
    speed = run_speed(run)
    if speed is None:
        return None
    return CEILING if speed == 0 else min(CEILING, speed * RATE_MARGIN)


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
