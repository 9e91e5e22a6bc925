"""Robots and tasks that are not in the application: reported, never part of the picture.

An id heard from the bus that the application does not have raises `unknown_robot` /
`unknown_task`. A flood of invented ids costs bounded memory: at most MAX_UNKNOWN ids are
remembered (and alarmed) at once, the rest only counted (`unknown_overflow`); an id is
forgotten `expiry` seconds after it was last heard — or after its last liveliness token went:
a token under `robot9/**` of a robot outside the team keeps its alarm up while it lives (at
most MAX_STRANGER_TOKENS tokens remembered per robot)."""

from __future__ import annotations

from typing import Callable

from mrta_zenoh import keys
from mrta_zenoh.untrusted import visible

from .alarms import Alarms

MAX_UNKNOWN = 100  # unknown robot / task ids remembered (and alarmed) at once
MAX_STRANGER_TOKENS = 16  # live tokens remembered per robot outside the application
MAX_NAME = 100  # characters of a name from the network shown in an alarm or a log line


class Strangers:
    def __init__(self, alarms: Alarms, counts: dict[str, int], expiry: float,
                 id_of: Callable[[str], str | None]):
        self.alarms, self.counts, self.expiry, self._id = alarms, counts, expiry, id_of
        self.seen: dict[tuple[str, str], float] = {}  # (kind, id) → last heard
        self.tokens: dict[str, set[str]] = {}         # unknown robot → its live tokens

    def heard(self, kind: str, ident: str, now: float) -> None:
        """`ident` (a robot or a task, by `kind`) was heard and is not the application's."""
        self.counts["unknown"] += 1
        k = (kind, ident)
        if k not in self.seen and len(self.seen) >= MAX_UNKNOWN:
            self.counts["unknown_overflow"] += 1
            return
        self.seen[k] = now
        self.alarms.raise_(f"unknown_{kind}", ident, now)

    def forget(self, kind: str, ident: str, now: float) -> None:
        """`ident` turned out to be the application's (a task submitted at run time, named
        before its change came): its alarm goes."""
        if self.seen.pop((kind, ident), None) is not None:
            self.alarms.clear(f"unknown_{kind}", ident, now)

    def token(self, key: str, alive: bool, now: float) -> None:
        """A token under `<id>/**` of a robot outside the application: `unknown_robot` while
        it lives (and `expiry` after), like a sample from it."""
        chunk = keys.first_chunk(key)
        rid = self._id(chunk)
        if rid is None:  # not even an id: shown escaped, counted
            self.counts["bad_keys"] += 1
            rid = visible(chunk, MAX_NAME)
        held = self.tokens.get(rid)
        if not alive:
            if held is not None:
                held.discard(key)
                if not held:
                    del self.tokens[rid]
            return
        self.counts["stranger_tokens"] += 1
        self.heard("robot", rid, now)
        if ("robot", rid) not in self.seen:  # over MAX_UNKNOWN: counted only
            return
        if held is None:
            held = self.tokens[rid] = set()
        if len(held) < MAX_STRANGER_TOKENS:
            held.add(key)

    def expire(self, now: float) -> None:
        for (kind, ident), seen in list(self.seen.items()):
            if kind == "robot" and ident in self.tokens:
                self.seen[(kind, ident)] = now  # its token still lives
            elif now - seen >= self.expiry:
                del self.seen[(kind, ident)]
                self.alarms.clear(f"unknown_{kind}", ident, now)

    def restart(self, now: float) -> None:
        """A new run: what is still remembered counts from its start (the old run's times
        are ahead of the new run's, and would never expire); the alarms are raised again."""
        for kind, ident in self.seen:
            self.seen[(kind, ident)] = now
            self.alarms.raise_(f"unknown_{kind}", ident, now)
