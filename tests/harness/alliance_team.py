"""A team of real ALLIANCE agents on virtual time, with an imperfect network between them.

Each robot is the agent `mrta agent` runs (mrta_agent.runtime.loop.Agent given ALLIANCE's
logic), driven through `Agent.schedule` — the very loop `Agent.run` sleeps through — on one
manual clock: the harness pops the earliest wake-up or delivery, sets the clock, and resumes
that robot's loop or hands it the broadcast. So its rates, catch-up rule, inbox, team and sender
checks, broadcast schedule and evaluator plugins are the production code's, not a copy. The
network delays every broadcast by a latency plus jitter, loses some, and honours partitions
(links cut for a time) and deaths (a robot stops). Everything is driven by one seeded random
generator, so a failing case replays exactly.
"""

from __future__ import annotations

import bisect
import heapq
import math
import random
from dataclasses import dataclass, field
from fractions import Fraction
from typing import Callable, Iterator

from mrta_agent.alliance.architecture import ALLIANCE, alliance_plugins
from mrta_agent.alliance.params import AgentParams, BehaviourSetParams, RobotParams
from mrta_agent.runtime.architecture import Prepared
from mrta_agent.runtime.loop import Agent
from mrta_agent.runtime.params import TaskParams
from mrta_zenoh.bus import Sample
from mrta_zenoh.clock import ManualClock

TASK = "t"
IRC = "inter_robot_communication"


@dataclass
class Spec:
    spin: float
    broadcast: float
    tau: float
    theta: float
    fast: float
    expected: float
    yielding: float
    giving_up: float = 1e6
    phase: float = 0.0

    def params(self, name: str) -> RobotParams:
        # the evaluator by module:Class, not by registered name: a name is looked up among
        # every installed package's entry points, and the properties build hundreds of agents
        bs = BehaviourSetParams(TASK, self.expected, self.theta, self.yielding, self.giving_up,
                                self.fast, "mrta_agent.runtime.builtin:UpdatedSensory", ())
        return RobotParams(name, self.spin, self.broadcast, self.tau, 10.0, (), (bs,))

    @property
    def tick(self) -> float:
        return 1.0 / self.spin

    def takeover_bound(self) -> float:
        """τ + ⌈θ/δ_fast⌉/ρ + one tick (ALLIANCE.takeover_bound), counted from the taker's
        last reception of any broadcast on the task. θ and δ_fast as the decimals they are
        (the strategies draw θ / ticks, which the agent adds up exactly)."""
        ticks = math.ceil(Fraction(repr(self.theta)) / Fraction(repr(self.fast)))
        return self.tau + (ticks + 1) / self.spin


@dataclass
class Network:
    latency: float = 0.005
    jitter: float = 0.0     # uniform extra delay in [0, jitter]
    loss: float = 0.0
    cuts: list[tuple[float, float, frozenset]] = field(default_factory=list)  # (from, to, robots)
    deaf: set[tuple[str, str]] = field(default_factory=set)  # (receiver, sender): one-way links
    # delivery delay of one broadcast (sender, receiver, send time) → seconds; replaces
    # latency + jitter when given (an adversary choosing each delay)
    delay: Callable[[str, str, float], float] | None = None
    # whether one broadcast (sender, receiver, send time) is lost, besides `loss` (an
    # adversary choosing which)
    lose: Callable[[str, str, float], bool] | None = None

    def cut(self, a: str, b: str, t: float) -> bool:
        """Is the link a–b down at time t (one side inside a cut group, the other outside)?"""
        return any(t0 <= t < t1 and ((a in g) != (b in g)) for t0, t1, g in self.cuts)


class _Handle:
    def close(self) -> None:
        pass


class HarnessBus:
    """What one robot's agent sees of the bus: its broadcasts go to the team's network, every
    other publication (motivations, feedback: monitoring) is dropped; the team's tokens are all
    alive from the start (a dead robot goes silent, as a crashed process's token outlives it by
    a lease)."""

    def __init__(self, team: "Team", name: str):
        self.team, self.name = team, name
        self.on_broadcast = None

    def subscribe(self, key_expr, handler, msg_type=None, **kwargs):
        if key_expr == ALLIANCE.every(IRC):
            self.on_broadcast = handler
        return _Handle()

    def watch_liveliness(self, key_expr, handler):
        for other in self.team.specs:
            handler(ALLIANCE.agent_token(other), True)
        return _Handle()

    def declare_token(self, key):
        return _Handle()

    def leave_unclaimed(self, key):
        """Monitoring: dropped here anyway (Bus.leave_unclaimed)."""

    def publish(self, key, message, lossy=False):
        if key == ALLIANCE.key(self.name, IRC):
            self.team._broadcast(self.name, key, message)


@dataclass
class Robot:
    name: str
    spec: Spec
    agent: Agent
    loop: Iterator[float] | None = None
    dead_at: float = math.inf

    @property
    def hl(self):
        return self.agent.coordinator.high


def make_agent(name: str, spec: Spec, bus: HarnessBus, clock: ManualClock) -> Agent:
    params = AgentParams(spec.params(name), {TASK: TaskParams(TASK, TASK, ())})
    plugins = alliance_plugins(params)  # the behaviour set's evaluator: UpdatedSensory
    prepared = Prepared(name, params, plugins, spec.spin, spec.spin, "team harness")
    agent = ALLIANCE.agent(prepared, bus, clock)
    agent.start()
    agent.declare_alive()
    return agent


class Team:
    def __init__(self, specs: dict[str, Spec], network: Network, seed: int = 0):
        self.rng = random.Random(seed)
        self.net = network
        self.specs = specs
        self.clock = ManualClock(0.0)
        self.buses = {n: HarnessBus(self, n) for n in specs}
        self.robots = {n: Robot(n, s, make_agent(n, s, self.buses[n], self.clock))
                       for n, s in specs.items()}
        self.events: list = []  # heap of (time, order, kind, data)
        self._order = 0
        for r in self.robots.values():
            self._push(r.spec.phase, "wake", r.name)
        self.now = 0.0
        self.timeline: list[tuple[float, frozenset]] = []   # (time, holders) at every change
        self.activations: dict[str, int] = {n: 0 for n in specs}
        self.resets: dict[str, int] = {n: 0 for n in specs}
        self.arrivals: dict[tuple[str, str], list[float]] = {}  # (receiver, sender) → arrivals
        self.losses: dict[frozenset, list[float]] = {}  # {a, b} → send times of lost broadcasts

    def _push(self, t: float, kind: str, data) -> None:
        heapq.heappush(self.events, (t, self._order, kind, data))
        self._order += 1

    def kill(self, name: str, t: float) -> None:
        self.robots[name].dead_at = t

    def holders(self) -> frozenset:
        return frozenset(n for n, r in self.robots.items()
                         if r.dead_at > self.now and r.hl.sets[TASK].active)

    def run(self, until: float) -> "Team":
        while self.events and self.events[0][0] <= until:
            t, _, kind, data = heapq.heappop(self.events)
            self.now = t
            self.clock.set(t)
            if kind == "wake":
                self._wake(self.robots[data])
            else:
                receiver, sample = data
                if self.robots[receiver].dead_at > t:
                    self.buses[receiver].on_broadcast(sample)
            holders = self.holders()
            if not self.timeline or self.timeline[-1][1] != holders:
                self.timeline.append((t, holders))
        return self

    def _wake(self, r: Robot) -> None:
        """Resume the robot's loop at the current time: it does the work due and says when it
        next wakes."""
        if r.dead_at <= self.now:
            return
        if r.loop is None:  # its process starts at its phase
            r.loop = r.agent.schedule()
            self._push(next(r.loop), "wake", r.name)
            return
        self._push(next(r.loop), "wake", r.name)
        history = r.agent.coordinator.history
        new = [tr for t, tr in history if t == self.now]
        for s in new:
            if s.kind == "activated":
                self.activations[r.name] += 1
            elif s.kind == "reset":
                self.resets[r.name] += 1

    def _broadcast(self, sender: str, key: str, message) -> None:
        sample = Sample(key, "alliance_msgs/InterRobotCommunication", message, b"")
        for other in self.robots:
            if other == sender:
                continue
            if (other, sender) in self.net.deaf:
                continue  # a one-way link: never heard (not a loss: no bound is skipped for it)
            lost = self.net.cut(sender, other, self.now) or self.rng.random() < self.net.loss \
                or (self.net.lose is not None and self.net.lose(sender, other, self.now))
            if lost:
                self.losses.setdefault(frozenset((sender, other)), []).append(self.now)
                continue
            if self.net.delay is not None:
                arrival = self.now + self.net.delay(sender, other, self.now)
            else:
                arrival = self.now + self.net.latency + self.rng.uniform(0.0, self.net.jitter)
            self.arrivals.setdefault((other, sender), []).append(arrival)
            self._push(arrival, "deliver", (other, sample))

    def drop_in_flight(self, sender: str, receiver: str) -> int:
        """Lose every broadcast from `sender` to `receiver` still on its way (an adversary
        acting at this instant); how many."""
        keep, dropped = [], []
        for ev in self.events:
            t, _, kind, data = ev
            if kind == "deliver" and data[0] == receiver and \
                    data[1].message.header.frame_id == sender:
                dropped.append(t)
            else:
                keep.append(ev)
        if dropped:
            heapq.heapify(keep)
            self.events = keep
            arrivals = self.arrivals[(receiver, sender)]
            for t in dropped:
                arrivals.remove(t)
            self.losses.setdefault(frozenset((sender, receiver)), []).append(self.now)
        return len(dropped)

    # ---------------------------------------------------------------- what happened
    def intervals(self, end: float) -> list[tuple[float, float, frozenset]]:
        out = []
        for (t0, h), nxt in zip(self.timeline, self.timeline[1:] + [(end, None)]):
            out.append((t0, nxt[0], h))
        return out

    def uncovered(self, start: float, end: float) -> float:
        """Longest stretch within [start, end] with no holder."""
        worst = 0.0
        for t0, t1, h in self.intervals(end):
            a, b = max(t0, start), min(t1, end)
            if b > a and not h:
                worst = max(worst, b - a)
        return worst

    def last_heard(self, receiver: str, until: float) -> float | None:
        """When `receiver` last received a teammate's broadcast (any sender) at or before
        `until`; None if never."""
        times = [t for (r, _), arrivals in self.arrivals.items() if r == receiver
                 for t in arrivals if t <= until]
        return max(times, default=None)

    def first_heard(self, receiver: str, sender: str, after: float) -> float:
        arrivals = sorted(self.arrivals.get((receiver, sender), ()))
        i = bisect.bisect_left(arrivals, after)
        return arrivals[i] if i < len(arrivals) else math.inf

    def lost_between(self, a: str, b: str, t0: float, t1: float) -> bool:
        sends = self.losses.get(frozenset((a, b)), ())
        i = bisect.bisect_left(sends, t0 - 5.0)
        return i < len(sends) and sends[i] <= t1
