"""An agent host: the agents of several robots in one process, each still a robot on the bus.

One interpreter and one Zenoh session per robot is right for real robots (a crash is a process
death), and it is what makes a robot cost what it costs in a study: an interpreter start and the
imports (≈ 0.5 CPU-s), a session with its lease and keep-alives, and a lockstep participant whose
every step crosses process boundaries. A host pays those once for K robots, the way ROS 2
composes many nodes in one process over one context (rmw_zenoh: one Zenoh session per context)
and ARGoS or Stage keep thousands of controllers behind one loop. What it does not change is
what makes each of them a robot:

* each robot keeps its keys (`robotN/...`), its liveliness tokens, its parameter files, its
  seed stream (`robot_rng(seed, id)`), its fault plan and its decision logic, and says
  everything over the bus — the host's one session delivers to its own subscribers, so what
  robot1 tells robot2 goes through the same message layer, fault channel and counting as
  between processes;
* one lockstep participant (named after the host) answers for all its robots (a SPEAKS token per
  robot, mrta_zenoh.lockstep): it waits for the earliest time any of them is due, then resumes
  each robot due by then, in id order, each on its own `Agent.schedule` generator — the loop
  the single-robot process runs, not a copy of it. A robot's messages at time t are heard by
  its teammates at their next tick, in a host as across processes (`loop.is_due`), so the order
  the host resumes them in changes nothing: a run with one host for the team gives the same
  summary as one process per robot (tests/process/test_hosts_identity.py);
* a robot's crash (fault injection) stops its agent and withdraws its tokens and subscriptions
  at the end of that round, with no goodbye — no zero-velocity command, no final tally — as the
  process death it stands for; the host and its other robots go on. The withdrawal is seen by
  the host's other robots before the host answers the step (`_wait_withdrawn`), and by every
  other process before the next step (the undeclaration travels before the host's StepDone on
  the same link), as a dead process's tokens are.

Where a host differs from processes (docs/architecture.md, "Agent hosts"): a crash of the host
is a crash of every robot in it at that instant; the host's CPU is shared, so a slow robot makes
its host-mates slow (lockstep keeps the run exact anyway); and a secured fleet is refused — its
access control certifies one robot per session.
"""

from __future__ import annotations

import functools
import logging
import threading
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

from mrta_zenoh.bus import Bus, BusOptions
from mrta_zenoh.clock import EPSILON, Clock
from mrta_zenoh.errors import ConfigError
from mrta_zenoh.failure import plan_from_env, say_crash
from mrta_zenoh.identity import ROBOT, certified
from mrta_zenoh.node import Node, NodeTime
from mrta_zenoh.seeds import robot_rng

from .host import AgentOptions, HostedAgent, clock_watchdog
from .loop import TEAM_WAIT

if TYPE_CHECKING:
    import numpy as np

log = logging.getLogger("mrta.host")

WITHDRAW_WAIT = 2.0  # wall s a host waits for its own robots to see a crashed one's tokens go


class Crashed(Exception):
    """A hosted robot's crash (fault injection): its agent stops, its host goes on."""


@dataclass(frozen=True)
class Seat:
    """One robot's place in a host: its options, as its architecture's verb would take them,
    and how its architecture builds its agent from the host's bus, clock and its random stream."""

    options: AgentOptions
    make_agent: Callable[[Bus, Clock, np.random.Generator], HostedAgent]
    describe: str
    warnings: tuple[str, ...] = ()
    logger: logging.Logger = log


def check_seats(seats: Sequence[Seat]) -> None:
    """What one host may run: at least one robot, each once, on one clock, seed and duration
    (they share the host's clock and node), and robots only (an architecture's own processes —
    central's dispatcher — are processes of their own)."""
    if not seats:
        raise ConfigError("an agent host needs at least one robot")
    ids = [s.options.robot_id for s in seats]
    twice = sorted({r for r in ids if ids.count(r) > 1})
    if twice:
        raise ConfigError(f"an agent host runs each robot once: {', '.join(twice)} given twice")
    first = seats[0].options
    for seat in seats[1:]:
        o = seat.options
        for what in ("sim_time", "seed", "duration"):
            if getattr(o, what) != getattr(first, what):
                raise ConfigError(f"the robots of one agent host share its clock, seed and "
                                  f"duration: {o.robot_id}'s {what} is {getattr(o, what)!r}, "
                                  f"{first.robot_id}'s {getattr(first, what)!r}")


def refuse_secured(bus_options: BusOptions) -> None:
    """A secured fleet's access control certifies one robot per session (mrta_zenoh.secure): a
    host would speak for robots its certificate is not for, so it is refused up front rather
    than left to publish into the void."""
    if bus_options.zenoh_config is None:
        return
    where = str(bus_options.zenoh_config)
    if certified(bus_options.user_config(), where) is not None:
        raise ConfigError("agent hosts run on an open bus only: a secured fleet certifies one "
                          "robot per process (run one agent per robot, --agents-per-process 1)",
                          file=where)


def host_agents(seats: Sequence[Seat], bus_options: BusOptions, *, name: str,
                stop: threading.Event | None = None, bus: Bus | None = None) -> int:
    """Run the seats' robots in this process until stopped or their duration ends (module
    docstring); 0 when done. `name`: the host's, its lockstep participant's; `bus`: an open bus
    to use instead of opening one (tests)."""
    check_seats(seats)
    refuse_secured(bus_options)
    first = seats[0].options
    robots = [s.options.robot_id for s in seats]
    # a bad $MRTA_FAULTS is bad input: before the bus, as a robot's own process does
    plans = [plan_from_env(s.options.robot_id, s.options.seed, s.options.crash_at) for s in seats]
    for seat in seats:
        for w in seat.warnings:
            seat.logger.warning("%s", w)
    node = Node(bus_options, ROBOT, name=name, stop=stop, bus=bus, speaks_for=robots,
                time=NodeTime.LOCKSTEP if first.sim_time else NodeTime.WALL)
    with node:
        agents = []
        try:
            for seat, plan in zip(seats, plans):
                agent = seat.make_agent(node.bus, node.clock,
                                        robot_rng(seat.options.seed, seat.options.robot_id))
                agent.limit_team(seat.options.team)
                agent.faults = plan
                agent.on_crash = functools.partial(_crash_in_host, agent)
                agent.start()
                agents.append(agent)
            for seat, agent in zip(seats, agents):  # alive means ready: every robot set up
                agent.declare_alive()
                seat.logger.info("%s: ready in host %s (%s, %s time)", agent.robot_id, name,
                                 seat.describe, "simulation" if first.sim_time else "wall")
                if agent.faults is not None:
                    seat.logger.info("%s: faults to inject: %s", agent.robot_id, agent.faults)
            log.info("%s: hosting %d robots: %s", name, len(agents), ", ".join(robots))
            watchdog = None
            if first.sim_time:
                watchdog = threading.Thread(
                    target=clock_watchdog,
                    args=(lambda: [a for a in agents if not a.withdrawn], node.clock, node.stop),
                    name="clock-watchdog", daemon=True)
                watchdog.start()
            try:
                if node.wait_for_clock():
                    for agent in agents:  # in lockstep: the team before the first tick
                        missing = agent.await_team(node.stop)
                        if missing:
                            agent.log.warning("%s: starting without %s: no agent token within "
                                              "%.0f s", agent.robot_id, ", ".join(missing),
                                              TEAM_WAIT)
                    until = None if first.duration is None else node.clock.now() + first.duration
                    drive(agents, node.clock, node.stop, until)
            finally:
                node.stop.set()
                if watchdog is not None:
                    watchdog.join(1.0)
        finally:
            for agent in agents:
                if not agent.withdrawn:
                    agent.shutdown()
    return 0


def _crash_in_host(agent: HostedAgent, now: float) -> None:
    """A hosted robot's crash: said as a robot's own process says it (the mission runner reads
    that line: supervisor hosting), then its agent stops (`drive` withdraws it)."""
    say_crash(agent.robot_id, now, agent.log)
    raise Crashed(agent.robot_id)


def drive(agents: Sequence[HostedAgent], clock: Clock, stop: threading.Event,
          until: float | None = None) -> None:
    """The host's loop: sleep on the one clock until the earliest time a robot is due, then
    resume, in id order, every robot due by the time the clock reached (each robot's own
    `schedule`: its rates, faults and restarts); withdraw those that crashed, at the end of the
    round. Ends when stopped or when every robot's schedule has ended."""
    order = sorted(agents, key=lambda a: a.robot_id)
    loops = {a.robot_id: a.schedule(until) for a in order}
    due: dict[str, float] = {}
    for agent in order:
        t = next(loops[agent.robot_id], None)
        if t is not None:
            due[agent.robot_id] = t
    while due and not stop.is_set():
        if not clock.sleep_until(min(due.values()), stop) or stop.is_set():
            return
        now = clock.now()
        crashed = []
        for agent in order:
            rid = agent.robot_id
            if rid not in due or due[rid] > now + EPSILON:
                continue
            try:
                t = next(loops[rid], None)
            except Crashed:
                crashed.append(agent)
                t = None
            if t is None:
                del due[rid]
            else:
                due[rid] = t
        for agent in crashed:
            agent.withdraw()
        if crashed:
            _wait_withdrawn([a for a in order if not a.withdrawn],
                            {a.robot_id for a in crashed}, stop)


def _wait_withdrawn(agents: Sequence[HostedAgent], gone: set[str],
                    stop: threading.Event) -> None:
    """Until the host's other robots no longer hear the crashed ones' tokens (the host's own
    session tells its subscribers as it tells other processes', but not necessarily before
    this thread goes on): a teammate in another process sees them go before the next step."""
    deadline = time.monotonic() + WITHDRAW_WAIT
    while not stop.is_set() and time.monotonic() < deadline:
        if not any(a.hears_alive(r) for a in agents for r in gone):
            return
        stop.wait(0.002)
    log.warning("host: %s still heard alive by its host-mates %.0f s after the crash",
                ", ".join(sorted(gone)), WITHDRAW_WAIT)
