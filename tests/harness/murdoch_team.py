"""A MURDOCH team on the in-process bus and one manual clock: real agents (plugins, auctions,
leases) stepped tick by tick in virtual time, with robots that can be killed (their bus closes,
so their token goes as a process exit takes it) or frozen (still "alive", never ticking)."""

from __future__ import annotations

from pathlib import Path
from typing import Callable

import numpy as np

from mrta_agent.murdoch.architecture import MURDOCH
from mrta_agent.runtime.host import AgentOptions
from mrta_agent.runtime.loop import Agent
from mrta_zenoh import keys
from mrta_zenoh.bus import InProcBus
from mrta_zenoh.bus.inproc import InProcNetwork
from mrta_zenoh.clock import ManualClock
from mrta_zenoh.messages import Header, Odometry, PointCloud, Pose2D, Twist
from tests.harness.alliance_fixtures import write

TIMING = {"spin_rate": 10.0, "bid_window": 0.5, "renewal_period": 0.5, "lease_timeout": 2.0,
          "reannounce_period": 2.0, "give_up_delay": 3.0}


# plugins by module:Class, not by registered name (alliance/odometry, …): a name is looked up
# among every installed package's entry points, and the properties build hundreds of agents
ODOMETRY = "mrta_agent.runtime.builtin:OdometrySensor"
POINT_CLOUD = "mrta_agent.runtime.builtin:PointCloudSensor"
UPDATED_SENSORY = "mrta_agent.runtime.builtin:UpdatedSensory"


def robot_doc(skills: dict[str, float], **timing) -> dict:
    doc = {"name": "test robot", **TIMING, **timing, "pose_topic": "odom",
           "utility": {"skill_weight": 1.0, "distance_weight": 0.1},
           "sensors": {"size": 2}, "skills": {"size": len(skills)}}
    for i, (t, plugin) in enumerate((("odom", ODOMETRY), ("sonar", POINT_CLOUD))):
        doc["sensors"][f"sensor{i}"] = {"plugin_name": plugin, "topic_name": t,
                                        "timeout_duration": 1.0}
    for i, (task, level) in enumerate(skills.items()):
        doc["skills"][f"skill{i}"] = {"task_id": task, "level": level, "progress": {
            "plugin_name": UPDATED_SENSORY,
            "sensors": {"size": 1, "sensor0": {"topic_name": "sonar"}}}}
    return doc


def tasks_doc(tasks: list[str], locations: dict[str, tuple[float, float]] | None = None,
              progress_timeout: float | None = None) -> dict:
    doc = {"tasks": {"size": len(tasks)}}
    for i, t in enumerate(tasks):
        loc = (locations or {}).get(t)
        doc["tasks"][f"task{i}"] = {
            "id": t, "name": t, "resources": {"size": 1, "resource0": {"topic_name": "sonar"}},
            "locations": {"size": 1, "location0": {"x": loc[0], "y": loc[1]}} if loc
            else {"size": 0}}
        if progress_timeout is not None:
            doc["tasks"][f"task{i}"]["progress_timeout"] = progress_timeout
    return doc


class Delays:
    """Delivery delays an adversary chooses, message by message, fed to the agent driver's own
    latency path (`Agent.faults`: a message is heard `delay` after it was sent and handled at
    the first tick at or after that — later messages may overtake it). Nothing is lost."""

    channel = True
    latency = (0.0, 0.0)  # set: the driver holds each message until its time
    loss = 0.0
    partitions = ()
    peers_cut = ()  # nobody is cut off
    first = None  # no fault names a robot by role
    range = None

    def __init__(self, robot: str, choose: Callable[[str, str, int], float]):
        self.robot, self.choose = robot, choose

    def delay(self, key: str, seq: int) -> float:
        return self.choose(self.robot, key, seq)

    def lost(self, key: str, seq: int) -> bool:
        return False

    def cut_off(self, t: float) -> bool:
        return False

    def out_of_range(self, here, there) -> bool:
        return False

    def stalled(self, now: float) -> bool:
        return False


class Team:
    def __init__(self, tmp: Path, skills: dict[str, dict[str, float]], tasks: list[str],
                 locations=None, start: float = 100.0, roster: list[str] | None = None,
                 delay: Callable[[str, str, int], float] | None = None,
                 progress_timeout: float | None = None, **timing):
        """`delay(receiver, key, seq)`: each coordination message's delivery delay (Delays)."""
        self.net = InProcNetwork()
        self.clock = ManualClock(start)
        tf = write(tmp / "tasks.yaml", tasks_doc(tasks, locations, progress_timeout))
        self.agents: dict[str, Agent] = {}
        self.buses: dict[str, InProcBus] = {}
        self.frozen: set[str] = set()
        self.blind: set[str] = set()  # robots whose sonar stopped
        self.pose: dict[str, tuple[float, float]] = {}
        self.observer = InProcBus(self.net)
        self.heard: list = []
        self.observer.subscribe("*/murdoch/**", self.heard.append)
        self.tokens: list[tuple[str, bool]] = []  # every liveliness change, in order
        self.observer.watch_liveliness("**", lambda key, alive: self.tokens.append((key, alive)))
        for rid, sk in skills.items():
            rf = write(tmp / f"{rid}.yaml", robot_doc(sk, **timing))
            bus = InProcBus(self.net)
            agent = MURDOCH.agent(MURDOCH.prepare(AgentOptions(rid, rf, tf)), bus, self.clock,
                                  np.random.default_rng(1))
            agent.limit_team(roster)  # None: anyone holding a token joins
            if delay is not None:
                agent.faults = Delays(rid, delay)
            agent.start()
            agent.declare_alive()
            self.agents[rid], self.buses[rid] = agent, bus

    def kill(self, rid: str) -> None:
        self.agents[rid].shutdown()
        self.buses[rid].close()
        del self.agents[rid]

    def step(self, n: int = 1) -> None:
        for _ in range(n):
            now = self.clock.now()
            for rid in self.agents:
                x, y = self.pose.get(rid, (0.0, 0.0))
                bus = self.buses[rid]
                bus.publish(keys.odom(rid), Odometry(Header(rid, now, 0), Pose2D(x, y, 0.0),
                                                     Twist(0.0, 0.0)))
                if rid not in self.blind:
                    bus.publish(keys.sonar(rid), PointCloud(Header(rid, now, 0), ()))
            for rid, agent in self.agents.items():
                if rid not in self.frozen:
                    agent.tick_high(now)
            self.clock.advance(0.1)

    def holders(self, task: str) -> list[str]:
        """Who holds `task`, among the robots still ticking (a frozen one believes what it
        believed when it froze)."""
        return sorted(r for r, a in self.agents.items()
                      if a.active_task == task and r not in self.frozen)

    def until(self, cond, limit: float = 30.0) -> float:
        """Step until cond() holds; the virtual seconds it took (AssertionError past limit)."""
        t0 = self.clock.now()
        while not cond():
            assert self.clock.now() - t0 < limit, f"not within {limit} s"
            self.step()
        return self.clock.now() - t0

    def messages(self, kind: str) -> list:
        """Every `kind` message on the bus, sub-keys included (`robot1/murdoch/bid/robot2`)."""
        return [s for s in self.heard if s.key.split("/")[2] == kind]
