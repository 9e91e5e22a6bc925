"""A delivery team in one process: every robot's agent built through its architecture's contract
(`prepare`, `agent`) from packages derived from an instance, with the real delivery plugins
(evaluator, layer, board), on one in-process network and one manual clock — and, for central,
its dispatcher in an agent driver of its own. The robots' bodies are unicycles that integrate
what each layer commands (`cmd_vel`) and report it as odometry, as a simulator without
obstacles would; a fault plan per process (loss, latency) goes through the real driver.

What it records is what a run's analysis reads: each robot's `delivery/started|done` events."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np

from mrta_agent.central.architecture import DISPATCHER
from mrta_agent.central.dispatcher import Dispatcher
from mrta_agent.central.params import DispatcherParams
from mrta_agent.runtime.host import AgentOptions
from mrta_agent.runtime.loop import Agent
from mrta_agent.runtime.plugins import Plugins
from mrta_delivery.generate import derive
from mrta_delivery.instance import InstanceDoc
from mrta_delivery.messages import TaskEvent
from mrta_zenoh import instances, keys
from mrta_zenoh.architectures import architectures
from mrta_zenoh.bus import InProcBus
from mrta_zenoh.bus.inproc import InProcNetwork
from mrta_zenoh.clock import ManualClock
from mrta_zenoh.failure import FaultPlan
from mrta_zenoh.messages import Header, Odometry, Pose2D, Twist
from mrta_zenoh.tasks.messages import CHANGE, INTAKE, Change

TICK = 0.1
PACKAGE = {"alliance": "delivery", "murdoch": "delivery_murdoch", "central": "delivery_central",
           "ssi": "delivery_ssi", "cbba": "delivery_cbba", "tessi": "delivery_tessi"}


class DeliveryTeam:
    def __init__(self, arch: str, doc: InstanceDoc, folder: Path,
                 faults: dict[str, FaultPlan] | None = None):
        derive(doc, folder)
        config = folder / PACKAGE[arch] / "config"
        self.contract = architectures()[arch]
        self.doc, self.problem = doc, doc.problem()
        self.net, self.clock = InProcNetwork(), ManualClock(0.0)
        self.world = InProcBus(self.net)
        self.events: list[tuple[str, str, str, float]] = []   # robot, task, event, stamp
        self.world.subscribe("*/delivery/*", lambda s: self.events.append(
            (keys.first_chunk(s.key), s.message.task_id, s.message.event,
             s.message.header.stamp)), msg_type=TaskEvent)
        self.pose = {rid: [float(r.start[0]), float(r.start[1]), math.radians(r.heading)]
                     for rid, r in doc.robots.items()}
        self.cmd = {rid: (0.0, 0.0) for rid in doc.robots}
        for rid in doc.robots:
            self.world.subscribe(keys.cmd_vel(rid), lambda s, rid=rid: self.cmd.__setitem__(
                rid, (s.message.linear, s.message.angular)), msg_type=Twist)
        self.agents: dict[str, Agent] = {}
        self.buses: list[InProcBus] = [self.world]
        faults = faults or {}
        name = self.contract.name
        for rid in doc.robots:
            layers = config / f"layers_{name}_params.yaml"
            prepared = self.contract.prepare(AgentOptions(
                rid, config / f"{rid}_{name}_params.yaml", config / f"tasks_{name}_params.yaml",
                layers if layers.exists() else None))
            self._start(rid, lambda bus, p=prepared: self.contract.agent(
                p, bus, self.clock, np.random.default_rng(0)), faults.get(rid))
        if arch == "central":  # with the instance its tasks submitted at run time grow
            loaded = instances.load(config / "instance.yaml")
            self._start(DISPATCHER, lambda bus: Agent(
                DISPATCHER, self.contract, lambda: Dispatcher(self.problem, DispatcherParams()),
                bus, self.clock, np.random.default_rng(0), Plugins((), (), {}, None, loaded),
                10.0, 10.0), faults.get(DISPATCHER))
        self.seq = 0

    def _start(self, name: str, make, plan: FaultPlan | None) -> None:
        bus = InProcBus(self.net)
        agent = make(bus)
        agent.faults = plan
        agent.start()
        agent.declare_alive()
        self.agents[name] = agent
        self.buses.append(bus)

    def step(self) -> None:
        now = self.clock.now()
        self.seq += 1
        for rid, (x, y, th) in self.pose.items():
            v, w = self.cmd[rid]
            self.world.publish(keys.odom(rid), Odometry(Header(rid, now, self.seq),
                                                        Pose2D(x, y, th), Twist(v, w)))
        for agent in self.agents.values():
            agent.tick_high(now)
        for agent in self.agents.values():
            agent.step_layers(now, TICK)
        for rid, pose in self.pose.items():  # a unicycle: what the layer commanded, for a tick
            v, w = self.cmd[rid]
            pose[2] += w * TICK
            pose[0] += v * math.cos(pose[2]) * TICK
            pose[1] += v * math.sin(pose[2]) * TICK
        self.clock.advance(TICK)

    def submit(self, task_id: str, fields: dict, priority: int = 0, op: str = "submit") -> float:
        """What the intake says when a task enters now (mrta_zenoh.tasks: `tasks/change`, its
        header the intake's): the instant it entered."""
        now = self.clock.now()
        self.seq += 1
        self.world.publish(CHANGE, Change(Header(INTAKE, now, self.seq), op, task_id,
                                          json.dumps(fields) if fields else "", priority,
                                          "ops"))
        return now

    def done(self) -> set[str]:
        return {task for _, task, event, _ in self.events if event == "done"}

    def run(self, until: float) -> None:
        """Until every task is done or past its due (and served, if it was being), or `until`."""
        last = max((t.due + t.service for t in self.problem.tasks if math.isfinite(t.due)),
                   default=until)
        while self.clock.now() < until:
            if len(self.done()) == len(self.problem.tasks) or self.clock.now() > last + 1.0:
                return
            self.step()

    def close(self) -> None:
        for agent in self.agents.values():
            agent.shutdown()
        for bus in self.buses:
            bus.close()
