"""Run one robot's ALLIANCE agent: what `mrta agent` does, callable from Python and tests.

Also what other tools may ask of ALLIANCE without knowing its internals: the takeover bound a
run is measured against (the patrol demo and `mrta experiment` use it).
"""

from __future__ import annotations

import logging
import math
import os
import threading
from pathlib import Path

from mrta_zenoh.bus import BusOptions, open_bus
from mrta_zenoh.clock import SimClock, WallClock, follow_sim_clock
from mrta_zenoh.lockstep import LockstepClock
from mrta_zenoh.errors import ConfigError
from mrta_zenoh.failure import parse_failure
from mrta_zenoh.keys import normalize_robot_id
from mrta_zenoh.lifecycle import stop_on_signals
from mrta_zenoh.seeds import robot_rng

from .agent import Agent, Plugins
from .params import AgentParams, load_agent_params, load_robot_params

log = logging.getLogger("mrta.agent")

# With no clock sample for this long (wall seconds), the robot is stopped: the simulator the
# robot follows is gone or hung, and a layer must not keep driving on a stale world.
CLOCK_WATCHDOG = 2.0


def prepare(*, robot_id: str, robot_params: Path, tasks_params: Path,
            layers_params: Path | None = None) -> tuple[str, AgentParams, Plugins]:
    """Everything that can fail on bad input, before any bus is opened (ConfigError → exit 2)."""
    rid = normalize_robot_id(robot_id)
    params = load_agent_params(robot_params, tasks_params, layers_params)
    plugins = Plugins(params)
    for name in plugins.unread_sections:
        params.warnings.append(params.layers.warning(
            (name,), f"section {name!r} is read by none of this robot's plugins"))
    return rid, params, plugins


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


def run_agent(*, robot_id: str, robot_params: Path, tasks_params: Path,
              layers_params: Path | None = None, bus_options: BusOptions,
              sim_time: bool = False, seed: int = 0, duration: float | None = None,
              crash_at: float | None = None, stop: threading.Event | None = None) -> int:
    rid, params, plugins = prepare(robot_id=robot_id, robot_params=robot_params,
                                   tasks_params=tasks_params, layers_params=layers_params)
    for w in params.warnings:
        log.warning("%s", w)
    crash = crash_time(rid, crash_at)
    clock = LockstepClock(rid) if sim_time else WallClock()
    with stop_on_signals(stop) as stop, open_bus(bus_options) as bus:
        agent = Agent(rid, params, bus, clock, robot_rng(seed, rid), plugins)
        # on simulation time, follow the clock, and take part in lockstep when the simulator
        # runs it (the participant token goes out before the agent's own: alive means ready)
        handles = follow_sim_clock(bus, clock) + clock.join(bus) if sim_time else []
        agent.start()
        agent.declare_alive()
        log.info("%s: ready (%d behaviour sets, %s time)", rid, len(params.robot.behaviour_sets),
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


def _clock_watchdog(agent: Agent, clock: SimClock, stop: threading.Event) -> None:
    """Say once that the clock stopped, and command zero velocity; say when it is back."""
    stopped = False
    while not stop.wait(0.25):
        if clock.stalled(CLOCK_WATCHDOG):
            if not stopped:
                stopped = True
                log.warning("%s: the simulation clock stopped at t=%.2f (no sample for %.0f s): "
                            "robot stopped until it comes back", agent.robot_id, clock.now(),
                            CLOCK_WATCHDOG)
                agent.ctx.publish_cmd(0.0, 0.0)
        elif stopped:
            stopped = False
            log.warning("%s: the simulation clock is back at t=%.2f", agent.robot_id, clock.now())


def takeover_bound(robot_params: Path, task: str) -> float:
    """τ + ⌈θ / fast_rate⌉ / ρ + one tick: the longest a robot with these parameters takes to
    pick up `task` after the robot doing it dies (its last broadcast lapses after τ, then
    impatience grows at fast_rate per tick from 0 to θ)."""
    robot, _ = load_robot_params(robot_params)
    for bs in robot.behaviour_sets:
        if bs.task_id == task:
            ticks = math.ceil(bs.threshold / bs.fast_rate)
            return robot.timeout_duration + (ticks + 1) / robot.spin_rate
    raise ConfigError(f"no behaviour set for task {task!r}", file=str(robot_params))
