"""Tasks that entered a delivery run at run time (issue 50, mrta_zenoh.tasks), read back from
the recording: the intake's `tasks/change` samples say what entered and when.

* `live_instance` — the instance the run served: its own tasks plus every task submitted, each
  arriving at the instant it entered (the allocation log and the metrics are computed on it, so a
  submitted task is assigned, served and measured as any other).
* `submitted` — the changes, as the summary's `instance` keeps them (`submitted`: a run of that
  instance replays them through its intake at the same instants — the instance's own `tasks`
  stay as they were, so the replay's packages and digest are the live run's).
* `accounting` — every task submitted, and every cancellation, with what became of it by the end:
  `served` (by whom, when), `assigned` (held, not done), `cancelled` (before anyone served it),
  `waiting` (nobody took it up); `served_after_cancel` names a task served after its
  cancellation (what must never happen: the cancellation reached its holder too late).
"""

from __future__ import annotations

import json
from typing import Any, Iterable

import msgspec

from mrta_zenoh.codec import DecodeError, decode, type_from_encoding
from mrta_zenoh.tasks.messages import CHANGE, INTAKE, Change, Op

from .instance import InstanceBody, SubmittedChange, TaskSpec


def changes(records: Iterable) -> list[Change]:
    """The intake's changes in the recording, in the order they entered (malformed or forged
    samples — another sender's header — are skipped)."""
    out = []
    for key, enc, _t, payload in records:
        if key != CHANGE:
            continue
        try:
            msg = decode(type_from_encoding(enc), payload)
        except DecodeError:
            continue
        if isinstance(msg, Change) and msg.header.frame_id == INTAKE:
            out.append(msg)
    return out


def cancellations(seen: list[Change]) -> dict[str, float]:
    """task → when it was first cancelled (the change's stamp, simulated s)."""
    out: dict[str, float] = {}
    for c in seen:
        if c.op == Op.CANCEL:
            out.setdefault(c.task_id, c.header.stamp)
    return out


def submitted(seen: list[Change]) -> list[SubmittedChange]:
    out = []
    for c in seen:
        task = None
        if c.op == Op.SUBMIT:
            task = msgspec.convert(json.loads(c.fields or "{}"), TaskSpec)
        out.append(SubmittedChange(round(c.header.stamp, 6), c.op, c.task_id, task, c.priority,
                                   c.submitter))
    return out


def live_instance(base: InstanceBody, seen: list[SubmittedChange]) -> InstanceBody:
    """`base` with every submitted task, arriving at the instant it entered."""
    tasks = dict(base.tasks)
    for c in seen:
        if c.op == Op.SUBMIT and c.task is not None and c.id not in tasks:
            tasks[c.id] = msgspec.structs.replace(c.task, arrival=c.at)
    return msgspec.structs.replace(base, tasks=tasks)


def accounting(seen: list[SubmittedChange], log: list, end: float) -> dict[str, Any]:
    """What became of every task submitted or cancelled (module docstring), and the counts."""
    rows: dict[str, dict[str, Any]] = {}
    for c in seen:
        row = rows.setdefault(c.id, {"id": c.id, "submitter": c.submitter, "entered_at": None,
                                     "priority": 0, "cancelled_at": None})
        if c.op == Op.SUBMIT:
            row.update(entered_at=c.at, priority=c.priority, submitter=c.submitter)
        elif c.op == Op.CANCEL:
            row["cancelled_at"] = c.at
        else:
            row["priority"] = c.priority
    late = []
    for tid, row in rows.items():
        mine = [e for e in log if e.task == tid]
        done = sorted((e.done_at, e.robot) for e in mine if e.done_at is not None)
        cancelled = row["cancelled_at"]
        if done and (cancelled is None or done[0][0] <= cancelled):
            row.update(state="served", robot=done[0][1], served_at=done[0][0])
        elif cancelled is not None:
            row.update(state="cancelled", robot=None, served_at=None)
        elif mine:
            row.update(state="assigned", robot=mine[-1].robot, served_at=None)
        else:
            row.update(state="waiting", robot=None, served_at=None)
        if cancelled is not None and any(d > cancelled for d, _ in done):
            late.append(tid)
    states = [r["state"] for r in rows.values()]
    return {"tasks": list(rows.values()), "served_after_cancel": late,
            "counts": {s: states.count(s) for s in ("served", "assigned", "cancelled",
                                                     "waiting")},
            "until": end}
