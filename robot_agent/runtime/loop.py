"""What every robot agent process shares, whatever its architecture: the two-rate loop on the
injected clock and the hosting around it (bus, simulation clock, lockstep, clock watchdog,
fault injection, signals).

ALLIANCE (mrta_agent.alliance.agent) and MURDOCH (mrta_agent.murdoch) both run on it, so a fix to timing,
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
