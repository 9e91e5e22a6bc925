"""The report layer's team ledger: time per robot and task, distance covered, border visited.

Made from what the team publishes on the bus, like a patrol leader's log. Only *teammates*
count: robots whose agent holds its liveliness token, heard on their own keys with a matching
`header/frame_id` — a forged `robot9` or a sample on robot1's key claiming to be robot2 adds
nothing. Who does what is read through the architecture contract (mrta_zenoh.architectures):
the agent token and "who is doing what" feed of the architecture the robot runs
(`ctx.architecture`), so the ledger works unchanged under ALLIANCE, MURDOCH or a third party's
architecture and names none of them.
Odometry is finite by construction (the message type rejects NaN and ±inf), so one bad sample
cannot turn every later report's distance into NaN.
"""

from __future__ import annotations

import math
import threading

from mrta_zenoh.keys import first_chunk
from mrta_zenoh.messages import Header, Odometry
from mrta_zenoh.architectures import Architecture
from mrta_agent.runtime.plugins import Plugin

from .messages import Report, TaskTime

MAX_TEAMMATES = 64


def rectangle_cells(x0: float, y0: float, x1: float, y1: float,
                    cell: float = 0.5) -> list[tuple[float, float]]:
    """Centres of ~`cell`-long pieces of a rectangle's perimeter, going round it once.

    "Share of the border visited" is the share of these cells someone came near."""
    out: list[tuple[float, float]] = []
    for (ax, ay), (bx, by) in (((x0, y0), (x1, y0)), ((x1, y0), (x1, y1)),
                               ((x1, y1), (x0, y1)), ((x0, y1), (x0, y0))):
        n = max(1, int(math.hypot(bx - ax, by - ay) / cell))
        out += [(ax + (bx - ax) * (i + 0.5) / n, ay + (by - ay) * (i + 0.5) / n) for i in range(n)]
    return out


class PatrolLedger:
    CELL = 0.5
    REACH = 2.0  # a border cell counts as visited when a robot passes within this distance

    def __init__(self, owner: Plugin, border: tuple[float, float, float, float] | None):
        """Subscribes through `owner`, so the owner's shutdown() closes the subscriptions."""
        self.clock = owner.ctx.clock
        self._lock = threading.Lock()
        self.teammates: set[str] = set()
        self.task_time: dict[tuple[str, str], float] = {}
        self._last_bc: dict[str, tuple[str, float]] = {}
        self._last_pos: dict[str, tuple[float, float]] = {}
        self.distance: dict[str, float] = {}
        self.cells = rectangle_cells(*border, self.CELL) if border is not None else []
        self.visited = [False] * len(self.cells)
        arch = owner.ctx.architecture
        self.gap = arch.doing_stale_after if arch is not None else 0.0
        if arch is not None:
            for key_expr, kind in arch.doing_feed():
                owner.subscribe(key_expr, lambda s, a=arch: self._on_doing(a, s), msg_type=kind)
            owner._subscriptions.append(owner.ctx.bus.watch_liveliness(arch.agent_tokens,
                                                                       self._on_token))
        owner.subscribe("*/odom", self._on_odom, msg_type=Odometry)

    def _on_token(self, key: str, alive: bool) -> None:
        with self._lock:
            if alive and len(self.teammates) < MAX_TEAMMATES:
                self.teammates.add(first_chunk(key))

    def _on_doing(self, arch: Architecture, sample) -> None:
        """Time on a task accrues between two reports of it from the same robot (at most the
        architecture's `doing_stale_after` apart: it repeats them at least that often); a
        report that the robot is no longer on it ends the stretch."""
        doing = arch.read_doing(sample.key, sample.message)
        if doing is None:
            return
        rid, now = doing.robot, self.clock.now()
        with self._lock:
            if rid not in self.teammates:
                return
            last = self._last_bc.get(rid)
            if not doing.active:
                if last is not None and last[0] == doing.task:
                    del self._last_bc[rid]
                return
            if last is not None and last[0] == doing.task and now - last[1] <= self.gap:
                k = (rid, doing.task)
                self.task_time[k] = self.task_time.get(k, 0.0) + (now - last[1])
            self._last_bc[rid] = (doing.task, now)

    def _on_odom(self, sample) -> None:
        rid = first_chunk(sample.key)
        p = sample.message.pose
        with self._lock:
            if rid not in self.teammates:
                return
            last = self._last_pos.get(rid)
            if last is not None:
                self.distance[rid] = self.distance.get(rid, 0.0) + math.hypot(p.x - last[0],
                                                                              p.y - last[1])
            self._last_pos[rid] = (p.x, p.y)
            for i, (cx, cy) in enumerate(self.cells):
                if not self.visited[i] and math.hypot(cx - p.x, cy - p.y) <= self.REACH:
                    self.visited[i] = True

    def report(self, reporter: str, now: float) -> Report:
        with self._lock:
            covered = sum(self.visited) / len(self.cells) if self.cells else 0.0
            times = tuple(TaskTime(r, t, s) for (r, t), s in sorted(self.task_time.items()))
            return Report(Header(reporter, now, 0), sum(self.distance.values()), covered, times)
