"""Who did which task when, from what the robots themselves said, in their (simulated) time.

The supervisor's view is built for operators: a robot counts as busy until its monitor's
timeout lapses, so it lags the robots by up to that timeout and, across a handover, can show one
robot on two tasks. Published metrics must equal what the robots did, so the mission runner
computes them from each architecture's own "who is doing what" feed
(`Architecture.read_doing`: ALLIANCE's Motivation samples, one per behaviour set per tick;
MURDOCH's claims and releases), stamped with the sender's clock — simulated time in simulated
runs, exact to one agent tick whatever the network or the machine's load did.

Rules, per robot: a report that it is active on a task opens (or extends) an interval; a report
that it is not, or an active report of another task, closes it at that report's stamp; a robot
that fails closes everything at its failure time; otherwise an interval not confirmed for
`stale_after` seconds ends at its last confirmation (a robot that died without being told to).
A robot is on at most one task at any time (single-task robots): opening a task closes the one
it was on.
"""

from __future__ import annotations

import dataclasses
import statistics
from dataclasses import dataclass, field
from typing import Iterable

from mrta_zenoh.architectures import Architecture, Decision, Doing
from mrta_zenoh.clock import EPSILON
from mrta_zenoh.codec import DecodeError, decode, type_from_encoding
from mrta_zenoh.keys import first_chunk, matches

from .summary import Decisions, Declared

Interval = tuple[str, float, float]  # (task, start, end)


@dataclass
class _Open:
    task: str
    start: float
    last: float


@dataclass
class GroundTruth:
    """Intervals per robot from Doing reports, fed in stamp order per robot."""

    stale_after: float
    intervals: dict[str, list[Interval]] = field(default_factory=dict)
    _open: dict[str, _Open] = field(default_factory=dict)

    def feed(self, d: Doing) -> None:
        cur = self._open.get(d.robot)
        if cur is not None and d.stamp - cur.last > self.stale_after:
            self._close(d.robot, cur.last)
            cur = None
        if d.active:
            if cur is not None and cur.task == d.task:
                cur.last = max(cur.last, d.stamp)
                return
            if cur is not None:
                self._close(d.robot, d.stamp)
            self._open[d.robot] = _Open(d.task, d.stamp, d.stamp)
        elif cur is not None and cur.task == d.task:
            self._close(d.robot, d.stamp)

    def fail(self, robot: str, at: float) -> None:
        """The robot stopped at `at` (an injected crash, exact in lockstep): what it held ends
        there — or at its last confirmation, if that is older than `stale_after`."""
        cur = self._open.get(robot)
        if cur is not None:
            self._close(robot, at if at - cur.last <= self.stale_after else cur.last)

    def finish(self, end: float) -> dict[str, list[Interval]]:
        """Close what is still open at `end` (the run's last simulated time), or at its last
        confirmation if that is older than `stale_after`."""
        for robot, cur in list(self._open.items()):
            self._close(robot, end if end - cur.last <= self.stale_after else cur.last)
        return self.intervals

    def _close(self, robot: str, at: float) -> None:
        cur = self._open.pop(robot)
        if at > cur.start:
            self.intervals.setdefault(robot, []).append((cur.task, cur.start, at))


def reports(records: Iterable, arch: Architecture) -> list[Doing]:
    """Every Doing in a recording, sorted by stamp (then robot, for a stable order); read once
    per recording read (recording.Recovered.memo) — the intervals, the stretches and an
    application's metrics all ask, and at 20 ALLIANCE robots each reading decodes ≈ 60,000
    motivations."""
    memo = getattr(records, "memo", None)
    if memo is None:
        return _reports(records, arch)
    key = ("reports", arch.name)
    if key not in memo:
        memo[key] = _reports(records, arch)
    return list(memo[key])


def _reports(records: Iterable, arch: Architecture) -> list[Doing]:
    feed = [expr for expr, _ in arch.doing_feed()]
    marker = f"/{arch.namespace}/"  # a cheap test first: most of a recording is sensor data
    out = []
    for key, enc, _t, payload in records:
        if marker not in key or not any(matches(expr, key) for expr in feed):
            continue
        try:
            msg = decode(type_from_encoding(enc), payload)
        except DecodeError:
            continue
        d = arch.read_doing(key, msg)
        if d is not None:
            out.append(d)
    out.sort(key=lambda d: (d.stamp, d.robot))
    return out


def intervals_from(records: Iterable, arch: Architecture, end: float, stale_after: float,
                   failures: Iterable[tuple[str, float]] = ()) -> dict[str, list[Interval]]:
    """robot → [(task, start, end)] from the recording's Doing reports."""
    truth = GroundTruth(stale_after)
    failed = dict(failures)
    for d in reports(records, arch):
        if d.robot in failed and d.stamp > failed[d.robot]:
            continue
        truth.feed(d)
    for robot, at in failed.items():
        truth.fail(robot, at)
    return truth.finish(end)


@dataclass
class Stretch:
    """One stretch a robot held a task: it entered the robot's queue at `assigned_at`, the
    robot set off to it at `started_at` (None: it never did), and it left the robot at
    `ended_at` (served, given back, or the robot stopped)."""

    robot: str
    task: str
    assigned_at: float
    started_at: float | None
    ended_at: float


def stretches_from(records: Iterable, arch: Architecture, end: float, stale_after: float,
                   failures: Iterable[tuple[str, float]] = ()) -> list[Stretch]:
    """Every stretch of every robot, in order of assignment. An architecture whose robots hold
    queues (Doing.queue) is read queue by queue: a task is the robot's from the first report
    that queues it until the first that does not (or the robot's failure, or its silence past
    `stale_after`). One without queues is assigned what it is on: its stretches are its
    intervals (`intervals_from`), set off to at once."""
    docs = reports(records, arch)
    if not any(d.queue is not None for d in docs):
        held = intervals_from(records, arch, end, stale_after, failures)
        return sorted((Stretch(robot, task, a, a, b) for robot, spans in held.items()
                       for task, a, b in spans), key=lambda s: (s.assigned_at, s.robot))
    failed = dict(failures)
    out: list[Stretch] = []
    held: dict[str, dict[str, Stretch]] = {}
    last: dict[str, float] = {}

    def close(robot: str, at: float, keep: frozenset[str] = frozenset()) -> None:
        for task in [t for t in held.get(robot, {}) if t not in keep]:
            s = held[robot].pop(task)
            s.ended_at = max(at, s.assigned_at)
            out.append(s)

    for d in docs:
        if d.robot in failed and d.stamp > failed[d.robot]:
            continue
        if d.robot in last and d.stamp - last[d.robot] > stale_after:
            close(d.robot, last[d.robot])
        last[d.robot] = d.stamp
        present = list(d.queue or ()) + ([d.task] if d.active and d.task not in (d.queue or ())
                                         else [])
        close(d.robot, d.stamp, frozenset(present))
        mine = held.setdefault(d.robot, {})
        for task in present:
            if task not in mine:
                mine[task] = Stretch(d.robot, task, d.stamp, None, d.stamp)
        if d.active and mine[d.task].started_at is None:
            mine[d.task].started_at = d.stamp
    for robot in list(held):
        at = failed.get(robot)
        if at is None:
            at = end if end - last.get(robot, end) <= stale_after else last[robot]
        close(robot, at)
    return sorted(out, key=lambda s: (s.assigned_at, s.robot, s.task))


def decisions(records, arch: Architecture, end: float) -> Decisions | None:
    """The allocation decisions the architecture's own messages record up to `end`
    (Architecture.decision): how many, and their computation time (median and largest, ms of
    the machine). None: the architecture records none (ALLIANCE's and MURDOCH's decisions
    are spread over every robot's ticks and leave no record of their cost)."""
    feed = [expr for expr, _ in arch.decision_feed()]
    if not feed:
        return None
    found, seen = [], set()
    for key, enc, _t, payload in records:
        if not any(matches(expr, key) for expr in feed):
            continue
        try:
            msg = decode(type_from_encoding(enc), payload)
        except DecodeError:
            continue
        header = getattr(msg, "header", None)
        if header is None or header.frame_id.strip("/") != first_chunk(key):
            continue
        d = arch.decision(first_chunk(key), key, msg)
        if d is None or d.stamp > end + EPSILON:
            continue
        if d.ident is not None:
            if (d.decider, d.ident) in seen:  # a repeat: read for who it leaves out only
                d = dataclasses.replace(d, counted=False)
            seen.add((d.decider, d.ident))
        found.append(d)
    made = [d for d in found if d.counted]
    times = sorted(d.ms for d in made)
    objectives = sorted({d.objective for d in made if d.objective})
    return Decisions(len(made), round(statistics.median(times), 3) if times else None,
                     round(times[-1], 3) if times else None, ", ".join(objectives) or None,
                     sum(1 for d in made if d.capped), declared(found))


def declared(found: list[Decision]) -> list[Declared]:
    """The robots each decider left out of its plan (Decision.out), as stretches: from the first
    decision that has it out for a reason to the first later one that has it back (or out for
    another reason); open at the end of the run."""
    out: list[Declared] = []
    open_: dict[tuple[str, str], Declared] = {}
    for d in sorted(found, key=lambda d: d.stamp):
        now = {robot: reason for robot, reason in d.out}
        for (decider, robot), stretch in list(open_.items()):
            if decider == d.decider and now.get(robot) != stretch.reason:
                stretch.until = round(d.stamp, 3)
                del open_[(decider, robot)]
        for robot, reason in now.items():
            if (d.decider, robot) not in open_:
                open_[(d.decider, robot)] = Declared(robot, reason, round(d.stamp, 3),
                                                     by=d.decider)
                out.append(open_[(d.decider, robot)])
    return out
