"""The client side of tasks at run time, what the `mrta task` verbs wrap (mrta_zenoh/cli/task.py):
a `Submitter` on an open bus sends requests on its own key and waits for the intake's answers.
Many requests go out at once and their answers are collected as they come (a burst of a
thousand takes one round trip, not a thousand).
"""

from __future__ import annotations

import itertools
import json
import os
import threading
import time
from dataclasses import dataclass
from typing import Any, Iterable

from ..errors import ConfigError, MrtaRuntimeError
from ..keys import is_id
from ..messages import Header
from .messages import Answer, Op, Request, answer_key, request_key
from .server import TOKEN


@dataclass(frozen=True)
class TaskRequest:
    """One request as a verb or a file states it."""

    op: Op
    task_id: str = ""
    fields: dict[str, Any] | None = None
    priority: int = 0


class Submitter:
    """Requests from `name` on an open bus (its answers on `tasks/answer/<name>`); a context
    manager (the subscription)."""

    def __init__(self, bus, name: str):
        if not is_id(name):
            raise ConfigError(f"submitter name {name!r}: letters, digits, '_', '-' or '.'")
        self.bus, self.name = bus, name
        self._answers: dict[str, Answer] = {}
        self._cond = threading.Condition()
        self._ids = itertools.count(1)
        self._prefix = f"{os.getpid()}-{time.monotonic_ns() % 10**9}"
        self._sub = bus.subscribe(answer_key(name), self._on_answer, msg_type=Answer)

    def __enter__(self) -> "Submitter":
        return self

    def __exit__(self, *exc) -> None:
        self._sub.close()

    def _on_answer(self, sample) -> None:
        with self._cond:
            self._answers[sample.message.request] = sample.message
            self._cond.notify_all()

    def wait_for_intake(self, timeout: float) -> None:
        """Until the run's intake is up (its token); MrtaRuntimeError naming what to check."""
        up = threading.Event()
        watch = self.bus.watch_liveliness(TOKEN, lambda _k, alive: alive and up.set())
        try:
            if not up.wait(timeout):
                raise MrtaRuntimeError(f"no task intake answered within {timeout:g} s: is a "
                                       "mission running on this rendezvous (`mrta demo "
                                       "--rendezvous`, $MRTA_RENDEZVOUS)?")
        finally:
            watch.close()

    def send(self, requests: Iterable[TaskRequest]) -> list[str]:
        """Send every request at once; their request ids, in order."""
        ids = []
        for r in requests:
            rid = f"{self._prefix}-{next(self._ids)}"
            fields = "" if r.fields is None else json.dumps(r.fields)
            self.bus.publish(request_key(self.name),
                             Request(Header(self.name, time.time(), len(ids)), rid, str(r.op),
                                     r.task_id, fields, r.priority))
            ids.append(rid)
        return ids

    def collect(self, ids: list[str], timeout: float) -> list[Answer | None]:
        """The answers to `ids`, in order (None: none came within `timeout` wall seconds)."""
        deadline = time.monotonic() + timeout
        with self._cond:
            while any(i not in self._answers for i in ids):
                left = deadline - time.monotonic()
                if left <= 0:
                    break
                self._cond.wait(min(left, 0.5))
            return [self._answers.pop(i, None) for i in ids]

    def ask(self, requests: list[TaskRequest], timeout: float) -> list[Answer | None]:
        return self.collect(self.send(requests), timeout)
