"""Hosting one robot agent process, whatever its architecture: parameter warnings, the node
(mrta_zenoh.node: identity, clock, signals, bus, lockstep), the run's random stream, the clock
watchdog and fault injection ($MRTA_FAULTS, and `--crash-at` as shorthand for a crash of its
own). `mrta agent` and `mrta murdoch` both end here."""

from __future__ import annotations

import logging
import threading
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Callable, Iterable, Iterator, Protocol

from mrta_zenoh.bus import Bus, BusOptions
from mrta_zenoh.clock import Clock, SimClock
from mrta_zenoh.errors import ConfigError
from mrta_zenoh.failure import FaultPlan, plan_from_env
from mrta_zenoh.identity import ROBOT
from mrta_zenoh.keys import normalize_robot_id
from mrta_zenoh.node import Node, NodeTime
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


class HostedAgent(Protocol):
    robot_id: str
    log: logging.Logger
    faults: FaultPlan | None
    ctx: object
    is_process: bool  # one of the architecture's processes (a dispatcher), not a robot
    withdrawn: bool  # crashed in an agent host (runtime.agent_host)
    on_crash: Callable[[float], None]

    def limit_team(self, team) -> None: ...
    def start(self) -> None: ...
    def declare_alive(self) -> None: ...
    def await_team(self, stop: threading.Event) -> list[str]: ...
    def run(self, stop: threading.Event, until: float | None = None) -> None: ...
    def schedule(self, until: float | None = None) -> Iterator[float]: ...
    def withdraw(self) -> None: ...
    def hears_alive(self, robot: str) -> bool: ...
    def shutdown(self) -> None: ...


def host(make_agent: Callable[[Bus, Clock, np.random.Generator], HostedAgent],
         options: AgentOptions, *, warnings: list[str], describe: str,
         stop: threading.Event | None = None, logger: logging.Logger = log,
         role: str = ROBOT) -> int:
    """Say the parameter warnings, start the node (on simulation time a lockstep participant
    named after the robot), build the agent with its random stream (from the run's seed and
    its id), declare it alive once it is ready, run until stopped — or until it crashes itself
    at its fault's time — then shut it down. `role`: a robot's, or that of a process the
    architecture runs beside its robots (central's dispatcher: `options.robot_id` is then its
    name), hosted the same way."""
    robot_id, sim_time = options.robot_id, options.sim_time
    # a bad $MRTA_FAULTS (or a second fault for this robot) is bad input: before the bus
    faults = plan_from_env(robot_id, options.seed, options.crash_at)
    for w in warnings:
        logger.warning("%s", w)
    node = Node(options.bus_options, role, name=robot_id, stop=stop,
                time=NodeTime.LOCKSTEP if sim_time else NodeTime.WALL)
    with node:
        agent = make_agent(node.bus, node.clock, robot_rng(options.seed, robot_id))
        agent.limit_team(options.team)  # before it listens: outsiders never join
        agent.faults = faults
        agent.start()
        agent.declare_alive()
        logger.info("%s: ready (%s, %s time)", robot_id, describe,
                    "simulation" if sim_time else "wall")
        if faults is not None:
            logger.info("%s: faults to inject: %s", robot_id, faults)
        watchdog = None
        if sim_time:
            watchdog = threading.Thread(target=clock_watchdog, args=(lambda: (agent,),
                                                                     node.clock, node.stop),
                                        name="clock-watchdog", daemon=True)
            watchdog.start()
        try:
            if node.wait_for_clock():
                missing = agent.await_team(node.stop)  # in lockstep: the team before the first tick
                if missing:
                    logger.warning("%s: starting without %s: no agent token within %.0f s",
                                   robot_id, ", ".join(missing), TEAM_WAIT)
            until = None if options.duration is None else node.clock.now() + options.duration
            agent.run(node.stop, until)
        finally:
            node.stop.set()
            if watchdog is not None:
                watchdog.join(1.0)
            agent.shutdown()
    return 0


def clock_watchdog(agents: Callable[[], Iterable[HostedAgent]], clock: SimClock,
                   stop: threading.Event) -> None:
    """Say once that the clock stopped, and command zero velocity to every robot `agents()`
    gives (one, or an agent host's robots still running); say when it is back
    (`watch_clock`, every quarter of a wall second)."""
    stopped = False
    while not stop.wait(0.25):
        stopped = watch_clock(agents, clock, stopped)


def watch_clock(agents: Callable[[], Iterable[HostedAgent]], clock: SimClock,
                stopped: bool) -> bool:
    """One look of the clock watchdog; returns whether the robots stand stopped by it.

    Not in lockstep. There simulated time standing still for seconds is the protocol waiting
    for a participant (a dispatcher's long search, the intake's burst, a loaded machine), and
    the world does not move meanwhile: nothing drives on blind. A zero command sent then, at a
    wall instant, reached the simulator as a command of the step after — the robot stood still
    for a step it would have driven, so two runs of one seed drifted by a tick or two wherever
    one of them was slow (a live `mrta demo --rendezvous` against its summary's replay). A
    lockstep run whose simulator is gone loses its barrier token, hence lockstep, and the
    watchdog stops the robots as before."""
    if clock.stalled(CLOCK_WATCHDOG) and not clock.in_lockstep():
        if not stopped:
            for agent in agents():
                agent.log.warning("%s: the simulation clock stopped at t=%.2f (no sample "
                                  "for %.0f s): robot stopped until it comes back",
                                  agent.robot_id, clock.now(), CLOCK_WATCHDOG)
                if not agent.is_process:  # a dispatcher has no body to stop
                    agent.ctx.publish_cmd(0.0, 0.0)
        return True
    if stopped:
        for agent in agents():
            agent.log.warning("%s: the simulation clock is back at t=%.2f", agent.robot_id,
                              clock.now())
    return False
