"""What every robot agent process shares, whatever its architecture: the two-rate loop on the
injected clock and the hosting around it (bus, simulation clock, lockstep, clock watchdog,
fault injection, signals).

ALLIANCE (robot_agent.agent) and MURDOCH (mrta_murdoch) both run on it, so a fix to timing,
lockstep or shutdown reaches both; an architecture supplies only its decision step
(`tick_high`), its layers (`step_layers`) and what a restart of time means to it (`restart`).
"""

from __future__ import annotations

import collections
import logging
import os
import signal
import threading
from typing import Callable, Protocol

import numpy as np

from mrta_zenoh.bus import Bus, BusOptions, open_bus
from mrta_zenoh.clock import EPSILON, Clock, SimClock, WallClock, follow_sim_clock
from mrta_zenoh.errors import ConfigError
from mrta_zenoh.failure import parse_failure
from mrta_zenoh.keys import normalize_robot_id
from mrta_zenoh.lifecycle import stop_on_signals
from mrta_zenoh.lockstep import LockstepClock
from mrta_zenoh.seeds import robot_rng

from .plugins import AgentContext, Layer, Plugins

log = logging.getLogger("mrta.agent")

# With no clock sample for this long (wall seconds), the robot is stopped: the simulator the
# robot follows is gone or hung, and a layer must not keep driving on a stale world.
CLOCK_WATCHDOG = 2.0


CRASH_ENV = "MRTA_CRASH"  # ROBOT@SECONDS[,ROBOT@SECONDS…]: fault injection for experiments


def crash_time(robot_id: str, crash_at: float | None) -> float | None:
    """When this robot's agent is to crash: --crash-at, or its entry in $MRTA_CRASH."""
    if crash_at is not None:
        return crash_at
    for item in filter(None, os.environ.get(CRASH_ENV, "").split(",")):
        try:
            failure = parse_failure(item.strip())
        except ValueError as exc:
            raise ConfigError(f"${CRASH_ENV}: {exc}") from None
        if failure.robot == robot_id:
            return failure.at
    return None


class AgentLoop:
    """The single-threaded loop: the decision step at `high_period`, the layers at
    `ctrl_period`, both scheduled on the injected clock so that the loop runs identically in
    real time, at k× simulation speed, in lockstep and step by step in tests.

    Also the low level's bookkeeping both architectures share: the inbox network callbacks fill
    and the loop drains (`heard`, `take_due`), and the active task's layers (`switch_layers`,
    `step_layers`, `reset_low_level`, `shutdown_low_level`).

    Subclasses call `__init__` with the robot, its bus, clock and plugins and their two rates,
    and implement `active_task`, `tick_high(now)` and `restart(now)`."""

    crash_at: float | None = None  # fault injection: SIGKILL itself at this time

    def __init__(self, robot_id: str, bus: Bus, clock: Clock, rng: np.random.Generator | None,
                 plugins: Plugins, spin_rate: float, control_rate: float,
                 logger: logging.Logger = log):
        self.robot_id = normalize_robot_id(robot_id)
        self.bus = bus
        self.clock = clock
        self.ctx = AgentContext(self.robot_id, bus, clock,
                                rng if rng is not None else robot_rng(0, self.robot_id),
                                log=logger)
        self.plugins = plugins
        self.high_period = 1.0 / spin_rate
        self.ctrl_period = 1.0 / control_rate
        self.log = logger
        # (time heard, *what): filled by network callbacks, drained by the loop thread only
        self._inbox: collections.deque = collections.deque(maxlen=10_000)

    def in_lockstep(self) -> bool:
        flag = getattr(self.clock, "lockstep", None)
        return flag is not None and flag.is_set()

    def heard_at(self, stamp: float) -> float:
        """When a message stamped `stamp` counts as heard: in lockstep every robot shares one
        simulated time, so its own stamp, exact whatever the network did; otherwise now."""
        return stamp if self.in_lockstep() else self.clock.now()

    def heard(self, stamp: float, *item) -> None:
        """Queue a message for the loop, timed by heard_at(stamp)."""
        self._inbox.append((self.heard_at(stamp), *item))

    def take_due(self, now: float) -> list[tuple]:
        """Every queued item due at `now`. In lockstep, one stamped at this very time waits for
        the next tick: the sender handled this step too, and what it said belongs after it."""
        lockstep = self.in_lockstep()
        due, later = [], []
        while self._inbox:
            item = self._inbox.popleft()
            (later if lockstep and item[0] >= now else due).append(item)
        self._inbox.extendleft(reversed(later))
        return due

    def _drop(self, counter: str, reason: str, *args) -> None:
        """Count a dropped message in `counter`; log the first and every 100th, so a flood (a
        forger, a misconfigured teammate) cannot flood the log."""
        n = getattr(self, counter) + 1
        setattr(self, counter, n)
        if n == 1 or n % 100 == 0:
            self.log.warning("%s: " + reason + " (%d so far)", self.robot_id, *args, n)

    @property
    def active_task(self) -> str | None:
        raise NotImplementedError

    def tick_high(self, now: float):
        raise NotImplementedError

    def restart(self, now: float) -> None:
        raise NotImplementedError

    # ------------------------------------------------------------ the active task's layers
    def layers_of(self, task: str | None) -> list[Layer]:
        return self.plugins.layers.get(task, []) if task is not None else []

    def switch_layers(self, before: str | None, after: str | None, now: float) -> bool:
        """The active task changed from `before` to `after`: terminate and initialise layers."""
        if before == after:
            return False
        for layer in self.layers_of(before):
            layer.on_deactivate(now)
        for layer in self.layers_of(after):
            layer.on_activate(now)
        return True

    def step_layers(self, now: float, dt: float) -> None:
        for layer in self.layers_of(self.active_task):
            layer.step(now, dt)

    def reset_low_level(self, now: float) -> None:
        """Time restarted (a new simulation run): the old run's world is gone — layers
        deactivated, sensors forgotten, queued messages dropped."""
        self.log.warning("%s: time restarted at t=%.2f (a new simulation run): starting afresh",
                         self.robot_id, now)
        for layer in self.layers_of(self.active_task):
            layer.on_deactivate(now)
        for sensor in self.plugins.sensors.values():
            sensor.forget()
        self._inbox.clear()

    def shutdown_low_level(self) -> None:
        """Stop the robot: deactivate the running layers, command zero velocity, and let every
        plugin close what it opened (py_trees' terminate, then shutdown)."""
        now = self.clock.now()
        for layer in self.layers_of(self.active_task):
            layer.on_deactivate(now)
        self.ctx.publish_cmd(0.0, 0.0)
        self.plugins.shutdown()

    def run(self, stop: threading.Event, until: float | None = None) -> None:
        high_period, ctrl_period = self.high_period, self.ctrl_period
        now = self.clock.now()
        next_high, next_ctrl, last_ctrl = now, now, now
        epoch = getattr(self.clock, "restarts", 0)
        while not stop.is_set():
            t = min(next_high, next_ctrl)
            if until is not None and t > until:
                break
            if not self.clock.sleep_until(t, stop):
                break
            now = self.clock.now()
            if self.crash_at is not None and now >= self.crash_at:
                self.log.warning("%s: crashing at t=%.2f as asked (fault injection)",
                                 self.robot_id, now)
                logging.shutdown()
                os.kill(os.getpid(), signal.SIGKILL)  # no shutdown, no goodbye: a real crash
            if getattr(self.clock, "restarts", 0) != epoch:
                epoch = self.clock.restarts
                self.restart(now)
                next_high, next_ctrl, last_ctrl = now, now, now
                if until is not None:
                    until = now + (until - t)
            if now >= next_high - EPSILON:
                self.tick_high(now)
                next_high += high_period
                if next_high <= now:  # fell behind: skip, don't burst
                    next_high = now + high_period
            if now >= next_ctrl - EPSILON:
                self.step_layers(now, now - last_ctrl)
                last_ctrl = now
                next_ctrl += ctrl_period
                if next_ctrl <= now:
                    next_ctrl = now + ctrl_period


class HostedAgent(Protocol):
    robot_id: str
    log: logging.Logger
    crash_at: float | None
    ctx: object

    def start(self) -> None: ...
    def declare_alive(self) -> None: ...
    def run(self, stop: threading.Event, until: float | None = None) -> None: ...
    def shutdown(self) -> None: ...


def host(make_agent: Callable[[Bus, Clock, np.random.Generator], HostedAgent], *,
         robot_id: str, warnings: list[str], seed: int, bus_options: BusOptions, sim_time: bool,
         duration: float | None, crash_at: float | None, stop: threading.Event | None,
         describe: str, logger: logging.Logger = log) -> int:
    """Say the parameter warnings, open the bus, build the agent with its random stream (from
    the run's seed and its id), follow simulation time (and lockstep) if asked, declare the
    agent alive once it is ready, run until stopped — or until it crashes itself at --crash-at
    or its $MRTA_CRASH entry — then shut it down."""
    crash = crash_time(robot_id, crash_at)  # a bad $MRTA_CRASH is bad input: before the bus
    for w in warnings:
        logger.warning("%s", w)
    clock = LockstepClock(robot_id) if sim_time else WallClock()
    with stop_on_signals(stop) as stop, open_bus(bus_options) as bus:
        agent = make_agent(bus, clock, robot_rng(seed, robot_id))
        # on simulation time, follow the clock, and take part in lockstep when the simulator
        # runs it (the participant token goes out before the agent's own: alive means ready)
        handles = follow_sim_clock(bus, clock) + clock.join(bus) if sim_time else []
        agent.start()
        agent.declare_alive()
        logger.info("%s: ready (%s, %s time)", robot_id, describe,
                    "simulation" if sim_time else "wall")
        if crash is not None:
            agent.crash_at = crash
        watchdog = None
        if sim_time:
            watchdog = threading.Thread(target=_clock_watchdog, args=(agent, clock, stop),
                                        name="clock-watchdog", daemon=True)
            watchdog.start()
        try:
            if sim_time:
                while not stop.is_set() and not clock.started.wait(0.1):
                    pass
            until = None if duration is None else clock.now() + duration
            agent.run(stop, until)
        finally:
            stop.set()
            if watchdog is not None:
                watchdog.join(1.0)
            agent.shutdown()
            for h in handles:
                h.close()
    return 0


def _clock_watchdog(agent: HostedAgent, clock: SimClock, stop: threading.Event) -> None:
    """Say once that the clock stopped, and command zero velocity; say when it is back."""
    stopped = False
    while not stop.wait(0.25):
        if clock.stalled(CLOCK_WATCHDOG):
            if not stopped:
                stopped = True
                agent.log.warning("%s: the simulation clock stopped at t=%.2f (no sample for "
                                  "%.0f s): robot stopped until it comes back", agent.robot_id,
                                  clock.now(), CLOCK_WATCHDOG)
                agent.ctx.publish_cmd(0.0, 0.0)
        elif stopped:
            stopped = False
            agent.log.warning("%s: the simulation clock is back at t=%.2f", agent.robot_id,
                              clock.now())
