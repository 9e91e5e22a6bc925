"""A team of ALLIANCE high levels on virtual time, with an imperfect network between them.

Each robot ticks at its own rate and phase, as `Agent.run` does: broadcasts received since the
last tick are applied with their reception times, then `HighLevel.tick`, then a broadcast when
one is due (broadcasts leave on ticks). The network delays every broadcast by a latency plus
jitter, loses some, and honours partitions (links cut for a time) and deaths (a robot stops).
Everything is driven by one seeded random generator, so a failing case replays exactly.
"""

from __future__ import annotations

import bisect
import heapq
import math
import random
from dataclasses import dataclass, field

from mrta_agent.alliance.high_level import HighLevel
from mrta_agent.alliance.params import BehaviourSetParams, RobotParams

TASK = "t"


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
        bs = BehaviourSetParams(TASK, self.expected, self.theta, self.yielding, self.giving_up,
                                self.fast, "alliance/updated_sensory", ())
        return RobotParams(name, self.spin, self.broadcast, self.tau, 10.0, (), (bs,))

    @property
    def tick(self) -> float:
        return 1.0 / self.spin

    def takeover_bound(self) -> float:
        """τ + ⌈θ/δ_fast⌉/ρ + one tick (mrta_agent.alliance.api.takeover_bound)."""
        return self.tau + (math.ceil(self.theta / self.fast - 1e-9) + 1) / self.spin


@dataclass
class Network:
    latency: float = 0.005
    jitter: float = 0.0     # uniform extra delay in [0, jitter]
    loss: float = 0.0
    cuts: list[tuple[float, float, frozenset]] = field(default_factory=list)  # (from, to, robots)

    def cut(self, a: str, b: str, t: float) -> bool:
        """Is the link a–b down at time t (one side inside a cut group, the other outside)?"""
        return any(t0 <= t < t1 and ((a in g) != (b in g)) for t0, t1, g in self.cuts)


@dataclass
class Robot:
    name: str
    spec: Spec
    hl: HighLevel
    inbox: list = field(default_factory=list)
    last_broadcast: float | None = None
    dead_at: float = math.inf


class Team:
    def __init__(self, specs: dict[str, Spec], network: Network, seed: int = 0):
        self.rng = random.Random(seed)
        self.net = network
        self.robots = {n: Robot(n, s, HighLevel(n, s.params(n))) for n, s in specs.items()}
        self.events: list = []  # heap of (time, order, kind, data)
        self._order = 0
        for r in self.robots.values():
            self._push(r.spec.phase, "tick", r.name)
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
            if kind == "tick":
                self._tick(self.robots[data])
            else:
                receiver, sender, hl_args = data
                r = self.robots[receiver]
                if r.dead_at > t:
                    r.inbox.append((sender, *hl_args, t))
            holders = self.holders()
            if not self.timeline or self.timeline[-1][1] != holders:
                self.timeline.append((t, holders))
        return self

    def _tick(self, r: Robot) -> None:
        if r.dead_at <= self.now:
            return
        for sender, expected, since, arrival in r.inbox:
            r.hl.on_broadcast(sender, TASK, expected, arrival, since)
        r.inbox.clear()
        r.hl.on_feedback(TASK, True, self.now)
        _, switches = r.hl.tick(self.now)
        for s in switches:
            if s.kind == "activated":
                self.activations[r.name] += 1
                r.last_broadcast = None
            elif s.kind == "reset":
                self.resets[r.name] += 1
        if r.hl.active_task is not None:
            period = 1.0 / r.spec.broadcast
            if r.last_broadcast is None or self.now - r.last_broadcast >= period - 1e-9:
                r.last_broadcast = self.now
                self._broadcast(r)
        self._push(self.now + r.spec.tick, "tick", r.name)

    def _broadcast(self, r: Robot) -> None:
        args = (r.spec.expected, r.hl.active_since())
        for other in self.robots:
            if other == r.name:
                continue
            lost = self.net.cut(r.name, other, self.now) or self.rng.random() < self.net.loss
            if lost:
                self.losses.setdefault(frozenset((r.name, other)), []).append(self.now)
                continue
            arrival = self.now + self.net.latency + self.rng.uniform(0.0, self.net.jitter)
            self.arrivals.setdefault((other, r.name), []).append(arrival)
            self._push(arrival, "deliver", (other, r.name, args))

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

    def first_heard(self, receiver: str, sender: str, after: float) -> float:
        arrivals = sorted(self.arrivals.get((receiver, sender), ()))
        i = bisect.bisect_left(arrivals, after)
        return arrivals[i] if i < len(arrivals) else math.inf

    def lost_between(self, a: str, b: str, t0: float, t1: float) -> bool:
        sends = self.losses.get(frozenset((a, b)), ())
        i = bisect.bisect_left(sends, t0 - 5.0)
        return i < len(sends) and sends[i] <= t1
