"""The report layer's team ledger: time per robot and task, distance covered, border visited.

Each robot keeps the log of its *own* work — distance from its own odometry, the border cells it
came near, time on each task from its own "who is doing what" feed — and publishes it, whole
and cumulative, on `robotN/patrol/log` about once per `Report/log_period` (simulated) seconds,
whether or not its report behaviour is active. A report is its own log merged with the latest
log of each teammate. Each robot's log is authoritative for itself; a teammate's part of a
report is up to one log period old.

Why each robot logs for itself: rebuilding every teammate's work from their raw feeds — every
robot's odometry at 10 Hz and every robot's architecture feed at every tick — and running the
border-cell loop on each odometry sample is N² samples per sensor period, and in lockstep every
agent must take them all before its next step (100 robots: 0.17× real time instead of 1.26×).
This way the team's traffic for the ledger is N² small messages per log period, and the cell
loop runs on the robot's own odometry only.

Only *teammates'* logs count: robots whose agent holds its liveliness token (read through the
architecture contract, mrta_zenoh.architectures, so the ledger names no architecture), heard on
their own key with a matching `header/frame_id`; a forged `robot9`, or a log on robot1's key
claiming to be robot2, adds nothing. The latest log of a robot whose token went away is kept:
its work still counts after it dies — and after it is restarted: a new agent process counts its
log from 1 again, and its earlier process's last log is kept beside the new ones. Two limits
follow from each robot logging for itself: a robot without the report layer publishes no log, so
its work is in nobody's report; and a restarted robot's own report starts from its restart (its
teammates still have the earlier part). A log made for another border (its cell count differs
from this robot's) is counted and ignored, never merged. Odometry is finite by construction
(the message type rejects NaN and ±inf), so one bad sample cannot poison a report.

Lockstep: a log is stamped with the odometry sample that triggers it (simulated time; the
simulator's sensor data reach an agent before the step they belong to), and a report at `now`
merges only teammates' logs stamped before `now` — those the lockstep barrier guarantees have
arrived — so what a report says does not depend on the network's scheduling.
"""

from __future__ import annotations

import collections
import math
import threading
from typing import NamedTuple

from mrta_zenoh import keys
from mrta_zenoh.architectures import Architecture
from mrta_zenoh.clock import EPSILON
from mrta_zenoh.errors import ConfigError
from mrta_zenoh.keys import first_chunk
from mrta_zenoh.messages import Header, Odometry
from mrta_agent.runtime.plugins import Plugin, heard_at

from .keys import ALL_LOGS, log_key
from .messages import PatrolLog, Report, TaskTime

# Teammates whose logs are kept (memory is bounded against invented robot ids). As many as the
# agent tracks tokens for (robot_agent/runtime/loop.py, MAX_TOKENS): a 100-robot swarm counts
# every robot's work. A log costs a few dozen bytes.
MAX_TEAMMATES = 1000


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


def _perimeter_distance(border: tuple[float, float, float, float], x: float, y: float) -> float:
    """How far (x, y) is from the rectangle's perimeter, from inside or outside."""
    x0, y0, x1, y1 = border
    if x0 <= x <= x1 and y0 <= y <= y1:
        return min(x - x0, x1 - x, y - y0, y1 - y)
    return math.hypot(max(x0 - x, 0.0, x - x1), max(y0 - y, 0.0, y - y1))


class CellGrid:
    """Border cells bucketed on a grid of side 2 × reach, so that a position is compared with
    the cells of the 3 × 3 buckets around it — every cell within `reach` is among them, with
    room to spare for rounding — instead of with all of them (a hall for 100 robots has ≈ 250
    cells, and a loop over them all would be most of an agent's odometry callback). The
    distance test itself is the same, so the cells visited are exactly those of the loop over
    every cell (tests/test_patrol_ledger_cells.py)."""

    def __init__(self, cells: list[tuple[float, float]], reach: float) -> None:
        self.reach = reach
        self.side = 2.0 * reach
        self.buckets: dict[tuple[int, int], list[tuple[int, float, float]]] = {}
        for i, (cx, cy) in enumerate(cells):
            self.buckets.setdefault(self._bucket(cx, cy), []).append((i, cx, cy))

    def _bucket(self, x: float, y: float) -> tuple[int, int]:
        return math.floor(x / self.side), math.floor(y / self.side)

    def visit(self, mask: int, x: float, y: float) -> int:
        """`mask` (bit i: cell i visited) with the cells within reach of (x, y) set."""
        bx, by = self._bucket(x, y)
        reach, buckets = self.reach, self.buckets
        for gx in (bx - 1, bx, bx + 1):
            for gy in (by - 1, by, by + 1):
                for i, cx, cy in buckets.get((gx, gy), ()):
                    if not mask >> i & 1 and math.hypot(cx - x, cy - y) <= reach:
                        mask |= 1 << i
        return mask


class _Log(NamedTuple):
    """A teammate's log as merged: its stamp, distance, cells (bit i: cell i), task times and
    sequence number (counted from 1 by each agent process)."""

    stamp: float
    distance: float
    visited: int
    times: dict[str, float]
    seq: int = 0


def _plus(a: _Log | None, b: _Log) -> _Log:
    """Two logs' work together (a robot's earlier agent process and its latest)."""
    if a is None:
        return b
    times = dict(a.times)
    for task, s in b.times.items():
        times[task] = times.get(task, 0.0) + s
    return _Log(max(a.stamp, b.stamp), a.distance + b.distance, a.visited | b.visited, times)


class PatrolLedger:
    CELL = 0.5
    REACH = 2.0  # a border cell counts as visited when a robot passes within this distance

    def __init__(self, owner: Plugin, border: tuple[float, float, float, float] | None,
                 period: float = 1.0):
        """Subscribes through `owner`, so the owner's shutdown() closes the subscriptions:
        its own odometry, its own part of the architecture's doing feed, every robot's log and
        the agents' tokens. Publishes its own log every `period` seconds of ctx.clock."""
        ctx = owner.ctx
        self.robot_id = ctx.robot_id
        self.bus = ctx.bus
        self.clock = ctx.clock
        self.log = ctx.log
        self.period = period
        self._lock = threading.Lock()
        self._publish_lock = threading.Lock()
        self.border = border
        self.cells = rectangle_cells(*border, self.CELL) if border is not None else []
        self._near = CellGrid(self.cells, self.REACH)
        self._nbytes = (len(self.cells) + 7) // 8
        # this robot's own work
        self.distance = 0.0
        self.visited = 0  # bit i: cell i
        self.task_time: dict[str, float] = {}
        self._last_pos: tuple[float, float] | None = None
        self._last_doing: tuple[str, float] | None = None
        # its log, at every multiple of the period: the whole team's logs go out at the same
        # step, one burst per period for each agent to take in (a 100-robot lockstep swarm ran
        # faster so than with each robot's logs spread over the period by a phase of its own)
        self._next_log: float | None = None
        self._seq = 0
        self.sent = 0
        # the team: robots that ever held a token (bounded), those holding one now, their logs
        # (latest and the one before, by arrival: a report takes the newest stamped before it)
        self.teammates: set[str] = set()
        self.alive: set[str] = set()
        self.logs: dict[str, tuple[_Log, _Log | None]] = {}
        # a teammate's work under its earlier agent processes (one restarted counts from 0 again)
        self.earlier: dict[str, _Log] = {}
        self.ignored: collections.Counter[str] = collections.Counter()
        arch = ctx.architecture
        self.gap = arch.doing_stale_after if arch is not None else 0.0
        if arch is not None:
            for key_expr, kind in arch.doing_feed():
                owner.subscribe(self._own_part(arch, key_expr),
                                lambda s, a=arch: self._on_doing(a, s), msg_type=kind)
        owner.subscribe(keys.odom(self.robot_id), self._on_odom, msg_type=Odometry)
        owner.subscribe(ALL_LOGS, self._on_log, msg_type=PatrolLog)
        if arch is not None:
            owner.watch_liveliness(arch.agent_tokens, self._on_token)

    def _own_part(self, arch: Architecture, key_expr: str) -> str:
        """This robot's part of a doing-feed key expression: `*/alliance/motivation/**` →
        `robot1/alliance/motivation/**`. The contract's feed is every robot's (its first chunk
        the robot); one that is not cannot be narrowed, and is refused rather than heard whole."""
        head, sep, rest = key_expr.partition("/")
        if head != "*" or not sep:
            raise ConfigError(f"architecture {arch.name!r}: doing feed {key_expr!r} does not "
                              "start with '*/' (a robot's chunk), so the patrol ledger cannot "
                              f"subscribe to {self.robot_id}'s part only")
        return f"{self.robot_id}/{rest}"

    # ------------------------------------------------------------ this robot's own work
    def _on_doing(self, arch: Architecture, sample) -> None:
        """Time on a task accrues between two reports of it (at most the architecture's
        `doing_stale_after` apart: it repeats them at least that often); a report that the
        robot is no longer on it ends the stretch. The robot's own stamps are used — its own
        clock, exact however late the sample is delivered — but never one ahead of that clock
        (a forgery on its key)."""
        doing = arch.read_doing(sample.key, sample.message)
        if doing is None or doing.robot != self.robot_id:
            return
        t = doing.stamp
        with self._lock:
            if t > self.clock.now() + EPSILON:
                self.ignored["future"] += 1
                return
            last = self._last_doing
            if not doing.active:
                if last is not None and last[0] == doing.task:
                    self._last_doing = None
                return
            if last is not None and last[0] == doing.task and 0.0 < t - last[1] <= self.gap:
                self.task_time[doing.task] = self.task_time.get(doing.task, 0.0) + (t - last[1])
            self._last_doing = (doing.task, t)

    def _on_odom(self, sample) -> None:
        """Distance and border cells from the robot's own odometry; the log goes out when one
        is due. In lockstep the sample's stamp is the time (`heard_at`, the Sensor rule): the
        agent's clock may still show the previous step."""
        msg = sample.message
        t = heard_at(self.clock, msg)
        x, y = msg.pose.x, msg.pose.y
        with self._lock:
            if self._last_pos is not None:
                self.distance += math.hypot(x - self._last_pos[0], y - self._last_pos[1])
            self._last_pos = (x, y)
            if self.border is not None and _perimeter_distance(self.border, x, y) <= self.REACH:
                self.visited = self._near.visit(self.visited, x, y)
            due = self._due(t)
        if due:
            self.publish_log(t)

    def _due(self, t: float) -> bool:
        """Whether a log is due at `t`: at the first sample at or after each multiple of the
        period. The first sample only sets the next time; so does one from before the last
        period (time went back: a new simulation run)."""
        nxt = self._next_log
        if nxt is not None and nxt - self.period - EPSILON <= t < nxt - EPSILON:
            return False
        self._next_log = (math.floor((t + EPSILON) / self.period) + 1) * self.period
        return nxt is not None and t >= nxt - EPSILON

    def own_log(self, t: float) -> PatrolLog:
        """This robot's log as of `t`."""
        with self._lock:
            self._seq += 1
            return PatrolLog(Header(self.robot_id, t, self._seq), self.distance, len(self.cells),
                             self.visited.to_bytes(self._nbytes, "little"),
                             tuple(TaskTime(self.robot_id, task, s)
                                   for task, s in sorted(self.task_time.items())))

    def publish_log(self, t: float) -> None:
        """Publish the log, lossy: it is cumulative, so a dropped one is made good by the next,
        and a full queue never blocks the network thread this runs on."""
        with self._publish_lock:
            self.bus.publish(log_key(self.robot_id), self.own_log(t), lossy=True)
            self.sent += 1

    # ------------------------------------------------------------ teammates' logs
    def _on_token(self, key: str, alive: bool) -> None:
        rid = first_chunk(key)
        if rid == self.robot_id:
            return
        with self._lock:
            if not alive:
                self.alive.discard(rid)  # its log stays: its work still counts
            elif rid in self.teammates or len(self.teammates) < MAX_TEAMMATES:
                self.teammates.add(rid)
                self.alive.add(rid)
            else:
                self.ignored["too_many"] += 1

    def _on_log(self, sample) -> None:
        rid, msg = first_chunk(sample.key), sample.message
        if rid == self.robot_id:
            return  # its own, heard back
        if msg.header.frame_id.strip("/") != rid or any(tt.robot_id != rid or tt.seconds < 0
                                                         for tt in msg.task_times):
            with self._lock:
                self.ignored["forged"] += 1  # about another robot than its sender
            return
        visited = int.from_bytes(msg.visited, "little")
        if msg.cells != len(self.cells) or len(msg.visited) != self._nbytes \
                or visited >> len(self.cells):
            with self._lock:
                self.ignored["other_border"] += 1
                first = self.ignored["other_border"] == 1
            if first:
                self.log.warning("%s: ignoring %s's patrol log: made for a border of %d cells, "
                                 "this robot's has %d (BorderProtection differs between robots?)",
                                 self.robot_id, rid, msg.cells, len(self.cells))
            return
        entry = _Log(msg.header.stamp, msg.distance, visited,
                     {tt.task_id: tt.seconds for tt in msg.task_times}, msg.header.seq)
        with self._lock:
            if rid not in self.alive:
                self.ignored["strangers"] += 1  # holds no agent token
                return
            kept = self.logs.get(rid)
            if kept is not None and entry.seq <= kept[0].seq:
                # its log count began again: a new agent process for that robot, whose log
                # starts from nothing — the earlier process's work is kept beside it
                self.earlier[rid] = _plus(self.earlier.get(rid), kept[0])
                kept = None
            self.logs[rid] = (entry, kept[0] if kept is not None else None)

    # ------------------------------------------------------------ the report
    def report(self, reporter: str, now: float) -> Report:
        """The team's work as of `now`: this robot's own, up to date, and of each teammate its
        latest log stamped before `now` (one stamped at `now` or later is left for the next
        report: in lockstep it may or may not have arrived yet)."""
        with self._lock:
            distance, visited = self.distance, self.visited
            times = {(self.robot_id, task): s for task, s in self.task_time.items()}
            for rid, (latest, before) in self.logs.items():
                log = latest if latest.stamp < now - EPSILON else before
                if log is None or log.stamp >= now - EPSILON:
                    log = None
                earlier = self.earlier.get(rid)
                log = _plus(earlier, log) if log is not None else earlier
                if log is None:
                    continue
                distance += log.distance
                visited |= log.visited
                times.update({(rid, task): s for task, s in log.times.items()})
        covered = visited.bit_count() / len(self.cells) if self.cells else 0.0
        return Report(Header(reporter, now, 0), distance, covered,
                      tuple(TaskTime(r, t, s) for (r, t), s in sorted(times.items())))
