"""The intake's rules (package docstring), pure: what a request may be, how much a submitter may
send, and what enters the run at each step boundary. The server (server.py) calls `offer` as a
request arrives (the network's threads, wall time) and `release` at each step boundary (its
simulated clock); tests drive both by hand.

Rules, each for a reason:

* **Nothing waits unbounded.** A submitter may send `burst` requests at once and `rate` a wall
  second after that (a token bucket per submitter); at most `pending` requests of all
  submitters wait for the next step boundary; a run takes at most `tasks` tasks at run time.
  Beyond any of them a request is refused at once, counted (refusal_tally: kind `task_request`,
  the submitter, the reason) and answered — a flood costs the intake a counter, not memory.
* **A malformed request is refused with its reason**, never half taken: an id that cannot be a
  key chunk, one the run already has, fields that are not a JSON object of at most
  MAX_FIELDS bytes, or fields the application's task type refuses (`admit`: its instance kind's,
  naming the field, with a "did you mean"). Counted as malformed in the refusal tally.
* **A change enters at a step boundary**: `release(now)` stamps everything accepted since the
  last boundary with `now`, in the order the requests arrived (a submitter's own order is kept:
  its requests arrive on one key). The order between two submitters' requests in one step is
  the network's; the run records what entered and when (`Change`), which is what replays.
* **A cancellation withdraws a task for good**; it is accepted for a task submitted or in the
  instance, not done yet as far as the intake knows (it does not know what robots did: a task
  cancelled after it was served stays served, and the summary says both).
* **Scheduled changes** (an instance's `submitted`: a run repeated from its summary) enter at
  their own instants, through the same path as live ones.
"""

from __future__ import annotations

import itertools
import json
import threading
import time
from collections import deque
from dataclasses import dataclass, field
from typing import Any, Callable, Iterable

from ..clock import EPSILON
from ..errors import ConfigError
from ..keys import is_id
from ..messages import Header
from ..refusal_tally import MALFORMED, MISMATCH, Refusals
from .messages import MAX_FIELDS, MAX_LISTING, INTAKE, Answer, Change, Op, Outcome, Request

KIND = "task_request"                 # refusal_tally kind of a refused request
RATE, FULL, TOO_MANY = "rate", "full", "too_many_tasks"  # refusal reasons beyond MALFORMED
CLOSED = "closed"  # the run serves no task submitted at run time (its architecture)


@dataclass(frozen=True)
class Limits:
    rate: float = 1000.0      # requests per wall second a submitter's bucket refills
    burst: int = 2000         # requests a submitter may send at once
    pending: int = 5000       # requests of all submitters waiting for the next step boundary
    tasks: int = 100_000      # tasks a run takes at run time, in all
    fields: int = MAX_FIELDS  # bytes of a task's fields


@dataclass
class Ledger:
    """One task the intake knows: submitted at run time, or the instance's own (`at` None)."""

    task_id: str
    submitter: str = ""
    at: float | None = None           # simulated instant it entered the run
    priority: int = 0
    fields: dict[str, Any] = field(default_factory=dict)
    cancelled_at: float | None = None

    def to_json(self) -> dict[str, Any]:
        return {"id": self.task_id, "submitter": self.submitter, "at": self.at,
                "priority": self.priority, "cancelled_at": self.cancelled_at,
                "fields": self.fields}


@dataclass(frozen=True)
class Scheduled:
    """A change an instance schedules (a run repeated from its summary)."""

    at: float
    op: Op
    task_id: str
    fields: dict[str, Any] = field(default_factory=dict)
    priority: int = 0
    submitter: str = ""


class _Bucket:
    def __init__(self, limits: Limits, now: float):
        self.tokens, self.at = float(limits.burst), now

    def take(self, limits: Limits, now: float) -> bool:
        self.tokens = min(float(limits.burst), self.tokens + (now - self.at) * limits.rate)
        self.at = now
        if self.tokens < 1.0:
            return False
        self.tokens -= 1.0
        return True


MAX_BUCKETS = 10_000  # submitters remembered (beyond: the oldest bucket is forgotten)


class Intake:
    """The rules (module docstring). `admit(task_id, fields)` raises ConfigError with the reason
    the application refuses a task; `known`: the instance's own task ids."""

    def __init__(self, admit: Callable[[str, dict[str, Any]], None], known: Iterable[str] = (),
                 limits: Limits = Limits(), schedule: Iterable[Scheduled] = (),
                 wall: Callable[[], float] = time.monotonic, closed: str = ""):
        """`closed`: why every submission is refused (the run's architecture grows no task at
        run time: Architecture.takes_submitted); "" — submissions are taken."""
        self.admit, self.limits, self.wall, self.closed = admit, limits, wall, closed
        self.tasks: dict[str, Ledger] = {t: Ledger(t) for t in known}
        self.submitted = 0
        self.refusals = Refusals()
        self.accepted = 0
        self._lock = threading.Lock()
        self._buckets: dict[str, _Bucket] = {}
        self._queue: deque[tuple[str, Request]] = deque()
        self._schedule = deque(sorted(schedule, key=lambda s: s.at))
        self._seq = itertools.count(1)
        self._count_lock = threading.Lock()

    # ------------------------------------------------------------------ the network's side
    def offer(self, submitter: str, req: Request) -> Answer | None:
        """A request as it arrives: queued for the next step boundary (None), or refused at once
        (its answer)."""
        with self._lock:
            bucket = self._buckets.get(submitter)
            if bucket is None:
                if len(self._buckets) >= MAX_BUCKETS:
                    self._buckets.pop(next(iter(self._buckets)))
                bucket = self._buckets[submitter] = _Bucket(self.limits, self.wall())
            if len(self._queue) >= self.limits.pending:
                return self._refuse(submitter, req, FULL, f"{self.limits.pending} requests are "
                                    "waiting for the next step: dropped")
            if not bucket.take(self.limits, self.wall()):
                return self._refuse(submitter, req, RATE, f"over {self.limits.rate:g} requests "
                                    f"a second (burst {self.limits.burst}): dropped")
            self._queue.append((submitter, req))
            return None

    def refuse_mismatch(self, sender: str, req: Request, why: str) -> Answer:
        """A request whose key and header name two submitters: refused and counted. Not marked
        forged (refusal_tally): a refused request changed nothing of the run, so it does not make
        the run another than its seed and its recorded changes describe."""
        with self._lock:
            return self._refuse(sender, req, MISMATCH, why)

    def refused(self) -> dict:
        """The refusal counts so far (refusal_tally entries), a copy."""
        with self._count_lock:
            return dict(self.refusals.counts)

    # ------------------------------------------------------------------ the step boundary
    def next_scheduled(self) -> float | None:
        with self._lock:
            return self._schedule[0].at if self._schedule else None

    def release(self, now: float) -> tuple[list[tuple[str, Answer]], list[Change]]:
        """Everything due at `now`: the scheduled changes up to it, then the requests queued
        since the last boundary, in arrival order. Returns (submitter, answer) pairs and the
        changes that entered, each stamped `now` (a scheduled one: its own instant)."""
        answers: list[tuple[str, Answer]] = []
        changes: list[Change] = []
        with self._lock:  # taken whole: the checks below run without holding the network's
            due = []      # threads (a receiver blocked past Zenoh's lease loses its link)
            while self._schedule and self._schedule[0].at <= now + EPSILON:
                due.append(self._schedule.popleft())
            queued, self._queue = self._queue, deque()
        for s in due:
            req = Request(Header(s.submitter, s.at, 0), "", str(s.op), s.task_id,
                          json.dumps(s.fields), s.priority)
            self._take(s.submitter, req, s.at, changes)
        for submitter, req in queued:
            answers.append((submitter, self._take(submitter, req, now, changes)))
        return answers, changes

    def _take(self, submitter: str, req: Request, now: float, changes: list[Change]) -> Answer:
        try:
            op = Op(req.op)
        except ValueError:
            return self._refuse(submitter, req, MALFORMED, f"unknown op {req.op!r} (submit, "
                                "cancel, reprioritize, list)")
        if op is Op.LIST:
            listing = json.dumps([t.to_json() for t in self.tasks.values() if t.at is not None])
            if len(listing) > MAX_LISTING:
                listing = json.dumps([{"id": t.task_id, "at": t.at,
                                       "cancelled_at": t.cancelled_at}
                                      for t in self.tasks.values() if t.at is not None])
            return self._answer(req, Outcome.LISTED, listing=listing)
        if op is Op.SUBMIT:
            return self._submit(submitter, req, now, changes)
        entry = self.tasks.get(req.task_id)
        if entry is None or entry.cancelled_at is not None:
            why = "no such task" if entry is None else f"cancelled at {entry.cancelled_at:g} s"
            return self._answer(req, Outcome.UNKNOWN, reason=why)
        if op is Op.CANCEL:
            entry.cancelled_at = now
        else:
            entry.priority = req.priority
        changes.append(self._change(op, entry, now, submitter))
        self.accepted += 1
        return self._answer(req, Outcome.ACCEPTED, at=now)

    def _submit(self, submitter: str, req: Request, now: float, changes: list[Change]) -> Answer:
        tid = req.task_id
        if self.closed:
            return self._refuse(submitter, req, CLOSED, self.closed)
        if not is_id(tid):
            return self._refuse(submitter, req, MALFORMED, f"task id {tid[:70]!r}: up to 64 of "
                                "letters, digits, '_', '-', '.', not starting with '-' or '.'")
        if tid in self.tasks:
            return self._refuse(submitter, req, MALFORMED, f"the run already has a task {tid!r}")
        if self.submitted >= self.limits.tasks:
            return self._refuse(submitter, req, TOO_MANY, f"the run took {self.limits.tasks} "
                                "tasks at run time already")
        if len(req.fields.encode()) > self.limits.fields:
            return self._refuse(submitter, req, MALFORMED, f"its fields are over "
                                f"{self.limits.fields} bytes")
        try:
            fields = json.loads(req.fields or "{}")
        except ValueError as exc:
            return self._refuse(submitter, req, MALFORMED, f"its fields are not JSON: {exc}")
        if not isinstance(fields, dict):
            return self._refuse(submitter, req, MALFORMED, "its fields are not a JSON object")
        try:
            self.admit(tid, fields)
        except ConfigError as exc:
            return self._refuse(submitter, req, MALFORMED, str(exc))
        entry = self.tasks[tid] = Ledger(tid, submitter, now, req.priority, fields)
        self.submitted += 1
        self.accepted += 1
        changes.append(self._change(Op.SUBMIT, entry, now, submitter))
        return self._answer(req, Outcome.ACCEPTED, at=now)

    def history(self) -> list[Change]:
        """The run's task set so far as the changes that make it (`tasks/history`: what a
        view started late asks for): each task that entered, with its priority now, and each
        cancellation, in the order of their instants. Bounded by the tasks the run has, not
        by how many changes it took (a flood of reprioritisations adds nothing). Called on the
        network's thread while `release` runs: `list` copies the ledger in one step."""
        out = []
        for n, entry in enumerate(list(self.tasks.values())):
            if entry.at is not None:
                out.append(((entry.at, 0, n), self._change(Op.SUBMIT, entry, entry.at,
                                                             entry.submitter)))
            if entry.cancelled_at is not None:
                out.append(((entry.cancelled_at, 1, n), self._change(
                    Op.CANCEL, entry, entry.cancelled_at, "")))  # by whom: not kept
        return [change for _, change in sorted(out, key=lambda c: c[0])]

    # ------------------------------------------------------------------ answers
    def _refuse(self, submitter: str, req: Request, reason: str, why: str) -> Answer:
        with self._count_lock:  # both threads refuse
            self.refusals.add(KIND, submitter, reason, False)
        return self._answer(req, Outcome.REFUSED, reason=f"{reason}: {why}")

    def _answer(self, req: Request, outcome: Outcome, *, reason: str = "", at: float = 0.0,
                listing: str = "") -> Answer:
        return Answer(Header(INTAKE, at, next(self._seq)), req.request, str(outcome),
                      req.task_id, reason[:300], at, listing)

    def _change(self, op: Op, entry: Ledger, now: float, submitter: str) -> Change:
        fields = json.dumps(entry.fields) if op is Op.SUBMIT else ""
        return Change(Header(INTAKE, now, 0), str(op), entry.task_id, fields, entry.priority,
                      submitter)
