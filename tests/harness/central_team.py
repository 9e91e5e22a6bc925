"""A central team on the in-process bus and one manual clock: the real dispatcher and the real
robot coordinators, each in the real agent driver (inbox, team tokens, sender checks, fault
channel), stepped tick by tick in virtual time. The robots' bodies are kinematic: a robot
drives straight to the task it is on at its speed and stays there its service time — what a
`Layer` would do — and can be killed (its bus closes: its token goes), stalled (its body stops,
its logic talks on) or cut off (a partition, through the driver's fault channel)."""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field

import numpy as np

from mrta_agent.central.agent import CentralCoordinator
from mrta_agent.central.architecture import CENTRAL, DISPATCHER
from mrta_agent.central.dispatcher import Dispatcher
from mrta_agent.central.params import CentralParams, DispatcherParams, RobotParams
from mrta_agent.runtime.loop import Agent
from mrta_agent.runtime.plugins import Plugins
from mrta_zenoh.bus import InProcBus
from mrta_zenoh.bus.inproc import InProcNetwork
from mrta_zenoh.clock import ManualClock
from mrta_zenoh.failure import FaultPlan
from mrta_zenoh.planning import Problem

TICK = 0.1


@dataclass
class Body:
    """A kinematic robot: where it is, what it finished since it last set off."""

    x: float
    y: float
    speed: float
    problem: Problem
    on: str | None = None
    arrived_at: float | None = None
    finished: set[str] = field(default_factory=set)
    stalled: bool = False
    blind: bool = False

    def applicable(self, task_id: str, now: float) -> bool:
        return not self.blind

    def withdrawn(self, task_id: str, now: float) -> bool:
        return False  # nothing is cancelled at run time in these teams

    def done(self, task_id: str, now: float) -> bool:
        return task_id in self.finished

    def pose(self) -> tuple[float, float, float]:
        return (self.x, self.y, 0.0)

    def move(self, task: str | None, now: float, dt: float) -> None:
        """One control step toward `task` (the coordinator's active task)."""
        if task != self.on:
            self.on, self.arrived_at = task, None
        if task is None or self.stalled or task in self.finished:
            return
        t = self.problem.tasks[self.problem.task_index(task)]
        gx, gy = t.position
        d = math.hypot(gx - self.x, gy - self.y)
        if d > 1e-9:
            step = min(d, self.speed * dt)
            self.x += (gx - self.x) / d * step
            self.y += (gy - self.y) / d * step
            return
        if self.arrived_at is None:
            self.arrived_at = max(now, t.arrival)
        if now >= self.arrived_at + t.service - 1e-9:
            self.finished.add(task)


def robot_params(report_period: float = 1.0, lease: float = 3.0) -> CentralParams:
    return CentralParams(RobotParams("r", 10.0, 10.0, report_period, lease, None, (), ()), {})


class Team:
    def __init__(self, problem: Problem, params: DispatcherParams = DispatcherParams(),
                 faults: dict[str, FaultPlan] | None = None, lease: float = 3.0):
        self.problem = problem
        self.net = InProcNetwork()
        self.clock = ManualClock(0.0)
        self.agents: dict[str, Agent] = {}
        self.buses: dict[str, InProcBus] = {}
        self.bodies: dict[str, Body] = {}
        self.served: dict[str, list[tuple[str, float]]] = {}   # robot → (task, when)
        self.active_log: list[tuple[float, str, str]] = []     # (t, robot, task) every step
        faults = faults or {}
        # every member honours the others' partitions, as plan_for gives each process them:
        # a cut-off robot still sends, and its receivers drop what it sent in its window
        cuts = tuple((name, a, b) for name, plan in faults.items() for a, b in plan.partitions)
        faults = {name: dataclasses.replace(faults.get(name) or FaultPlan(name, 0), peers_cut=tuple(
            c for c in cuts if c[0] != name)) for name in [*(r.id for r in problem.robots),
                                                            DISPATCHER]}
        team = [r.id for r in problem.robots]
        for r in problem.robots:
            body = self.bodies[r.id] = Body(*r.start, r.speed, problem)
            self._add(r.id, lambda rid=r.id, b=body: CentralCoordinator(
                rid, robot_params(lease=lease), dispatcher=DISPATCHER, readings=b),
                10.0, team, faults.get(r.id))
        self._add(DISPATCHER, lambda: Dispatcher(problem, params), params.spin_rate, team,
                  faults.get(DISPATCHER))

    def _add(self, name, make, rate, team, plan) -> None:
        bus = InProcBus(self.net)
        agent = Agent(name, CENTRAL, make, bus, self.clock, np.random.default_rng(0),
                      Plugins((), (), {}, None), rate, rate)
        agent.limit_team(team)
        agent.faults = plan
        agent.start()
        agent.declare_alive()
        self.agents[name], self.buses[name] = agent, bus

    @property
    def dispatcher(self) -> Dispatcher | None:
        agent = self.agents.get(DISPATCHER)
        return None if agent is None else agent.coordinator

    def kill(self, name: str) -> None:
        self.agents[name].shutdown()
        self.buses[name].close()
        del self.agents[name]

    def step(self, n: int = 1) -> None:
        for _ in range(n):
            now = self.clock.now()
            for name, agent in list(self.agents.items()):
                agent.tick_high(now)
            for rid, body in self.bodies.items():
                agent = self.agents.get(rid)
                if agent is None:
                    continue
                task = agent.coordinator.active_task
                if task is not None:
                    self.active_log.append((now, rid, task))
                before = set(body.finished)
                body.move(task, now, TICK)
                for t in body.finished - before:
                    self.served.setdefault(rid, []).append((t, now))
            self.clock.advance(TICK)

    def until(self, cond, limit: float = 200.0) -> float:
        t0 = self.clock.now()
        while not cond():
            assert self.clock.now() - t0 < limit, f"not within {limit} s"
            self.step()
        return self.clock.now() - t0

    def all_served(self) -> bool:
        return len(self.served_tasks()) == len(self.problem.tasks)

    def served_tasks(self) -> list[str]:
        return [t for route in self.served.values() for t, _ in route]

    def routes(self) -> dict[str, list[str]]:
        return {r: [t for t, _ in route] for r, route in self.served.items()}

    def simultaneous(self) -> list[tuple[float, str, set[str]]]:
        """Every instant at which two robots were on one task at once."""
        by: dict[tuple[float, str], set[str]] = {}
        for t, robot, task in self.active_log:
            by.setdefault((t, task), set()).add(robot)
        return [(t, task, robots) for (t, task), robots in sorted(by.items()) if len(robots) > 1]
