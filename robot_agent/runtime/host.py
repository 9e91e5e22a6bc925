"""Hosting one robot agent process, whatever its architecture: parameter warnings, the bus, the
run's random stream, simulation time and lockstep, the clock watchdog, fault injection
($MRTA_CRASH, --crash-at, $MRTA_FAULTS) and signals. `mrta agent` and `mrta murdoch` both end
here."""

from __future__ import annotations

import contextlib
import logging
import os
import threading
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Callable, Protocol

from mrta_zenoh.bus import Bus, BusOptions, open_bus
from mrta_zenoh.clock import Clock, SimClock, WallClock, follow_sim_clock
from mrta_zenoh.architectures import CRASH_ENV, FAULTS_ENV
from mrta_zenoh.errors import ConfigError
from mrta_zenoh.failure import FaultPlan, Faults, parse_failure, parse_faults, plan_for
from mrta_zenoh.identity import ROBOT, check_identity
from mrta_zenoh.keys import normalize_robot_id
from mrta_zenoh.lifecycle import stop_on_signals
from mrta_zenoh.lockstep import LockstepClock
from mrta_zenoh.seeds import robot_rng

from .loop import TEAM_WAIT

if TYPE_CHECKING:
    import numpy as np  # annotations only: numpy loads when a plugin draws (mrta_zenoh.seeds)

log = logging.getLogger("mrta.agent")

# With no clock sample for this long (wall seconds), the robot is stopped: the simulator the
# robot follows is gone or hung, and a layer must not keep driving on a stale world.
CLOCK_WATCHDOG = 2.0


@dataclass(frozen=True)
class AgentOptions:
    """One robot agent's options, whatever its architecture: its parameter files, its clock,
    the run's seed, how long to run, fault injection and the bus. Built once by the verb
    (`agent_command`), by a test or by a launch file's node, and read here."""

    robot_id: str
    robot_params: Path
    tasks_params: Path
    layers_params: Path | None = None
    bus_options: BusOptions = field(default_factory=BusOptions)
    sim_time: bool = False
    seed: int = 0
    duration: float | None = None
    crash_at: float | None = None
    team: tuple[str, ...] | None = None  # --team: the only robots it counts (None: any)

    def __post_init__(self) -> None:
        # one spelling of the id everywhere: the logic compares ids (ALLIANCE's tie-break,
        # MURDOCH's awards), so `/robot1` must be `robot1` before anything is built
        object.__setattr__(self, "robot_id", normalize_robot_id(self.robot_id))
        if self.team is not None:
            team = tuple(dict.fromkeys(normalize_robot_id(r) for r in self.team))
            if self.robot_id not in team:
                raise ConfigError(f"--team {','.join(team)}: {self.robot_id} is not on its own "
                                  "team")
            object.__setattr__(self, "team", team)


def env_faults() -> Faults:
    """$MRTA_FAULTS parsed (empty if unset); a bad one is a ConfigError, before the bus."""
    text = os.environ.get(FAULTS_ENV, "")
    if not text:
        return Faults()
    try:
        return parse_faults(text)
    except ValueError as exc:
        raise ConfigError(f"${FAULTS_ENV}: {exc}") from None


def fault_plan(robot_id: str, seed: int) -> FaultPlan | None:
    """This robot's stall, partitions, loss and latency from $MRTA_FAULTS (the run's seed
    draws which messages are lost or late), or None."""
    return plan_for(env_faults(), robot_id, seed)


def crash_time(robot_id: str, crash_at: float | None) -> float | None:
    """When this robot's agent is to crash: --crash-at, or its entry in $MRTA_CRASH (or a
    crash item in $MRTA_FAULTS: honoured, not ignored)."""
    if crash_at is not None:
        return crash_at
    for f in env_faults().failures:
        if f.kind == "crash" and f.robot == robot_id:
            return f.at
    for item in filter(None, os.environ.get(CRASH_ENV, "").split(",")):
        try:
            failure = parse_failure(item.strip())
        except ValueError as exc:
            raise ConfigError(f"${CRASH_ENV}: {exc}") from None
        if failure.robot == robot_id:
            return failure.at
    return None


class HostedAgent(Protocol):
    robot_id: str
    log: logging.Logger
    crash_at: float | None
    faults: FaultPlan | None
    ctx: object

    def limit_team(self, team) -> None: ...
    def start(self) -> None: ...
    def declare_alive(self) -> None: ...
    def await_team(self, stop: threading.Event) -> list[str]: ...
    def run(self, stop: threading.Event, until: float | None = None) -> None: ...
    def shutdown(self) -> None: ...


def host(make_agent: Callable[[Bus, Clock, np.random.Generator], HostedAgent],
         options: AgentOptions, *, warnings: list[str], describe: str,
         stop: threading.Event | None = None, logger: logging.Logger = log) -> int:
    """Say the parameter warnings, open the bus, build the agent with its random stream (from
    the run's seed and its id), follow simulation time (and lockstep) if asked, declare the
    agent alive once it is ready, run until stopped — or until it crashes itself at --crash-at
    or its $MRTA_CRASH entry — then shut it down."""
    robot_id, sim_time = normalize_robot_id(options.robot_id), options.sim_time
    crash = crash_time(robot_id, options.crash_at)  # a bad $MRTA_CRASH is bad input: before the bus
    faults = fault_plan(robot_id, options.seed)
    for w in warnings:
        logger.warning("%s", w)
    # a fleet certificate that is not this robot's is refused before the bus opens
    check_identity(options.bus_options, ROBOT, robot_id)
    clock = LockstepClock(robot_id) if sim_time else WallClock()
    with stop_on_signals(stop) as stop, open_bus(options.bus_options) as bus, \
            contextlib.ExitStack() as handles:
        agent = make_agent(bus, clock, robot_rng(options.seed, robot_id))
        agent.limit_team(options.team)  # before it listens: outsiders never join
        # on simulation time, follow the clock, and take part in lockstep when the simulator
        # runs it (the participant token goes out before the agent's own: alive means ready)
        if sim_time:
            handles.enter_context(follow_sim_clock(bus, clock))
            handles.enter_context(clock.join(bus))
        agent.start()
        agent.declare_alive()
        logger.info("%s: ready (%s, %s time)", robot_id, describe,
                    "simulation" if sim_time else "wall")
        if crash is not None:
            agent.crash_at = crash
        if faults is not None:
            agent.faults = faults
            logger.info("%s: faults to inject: %s", robot_id, faults)
        watchdog = None
        if sim_time:
            watchdog = threading.Thread(target=_clock_watchdog, args=(agent, clock, stop),
                                        name="clock-watchdog", daemon=True)
            watchdog.start()
        try:
            if sim_time:
                while not stop.is_set() and not clock.started.wait(0.1):
                    pass
                missing = agent.await_team(stop)  # in lockstep: the team before the first tick
                if missing:
                    logger.warning("%s: starting without %s: no agent token within %.0f s",
                                   robot_id, ", ".join(missing), TEAM_WAIT)
            until = None if options.duration is None else clock.now() + options.duration
            agent.run(stop, until)
        finally:
            stop.set()
            if watchdog is not None:
                watchdog.join(1.0)
            agent.shutdown()
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
