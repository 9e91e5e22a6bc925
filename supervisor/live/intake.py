"""Sample intake: a monitored sample becomes a reading — the ids its monitors' fields hold —
or is counted and dropped, before anything of the supervisor's picture changes.

What the bus cannot be trusted with (docs/architecture.md):
* every id is checked (one key chunk, ≤ 64 characters) before it reaches any state; a sample
  is used whole or not at all (`field_errors`, `wrong_type`);
* where a monitor's key expression starts with a wildcard (`*/alliance/…`), the first chunk of a
  sample's key is the publishing robot: a sample whose robot field names another robot is
  dropped and counted (`key_mismatch`) — robot1 cannot make robot2 look busy — and a sample
  from a robot outside the application is recognised before any field is read
  (`unknown_robot`, strangers.py); a key whose first chunk is no id is counted (`bad_keys`).

The hot path: a sample that says again what the last accepted sample on its key said (same
type, same field values) while every state it holds is still high only moves those holders'
deadlines — one C-level read of all fields, a dict lookup, a comparison. Anything else (a new
value, a state that fell, a robot that went offline, a bad sample) takes the full path, which
is also what fills the cache."""

from __future__ import annotations

import logging
import threading
from typing import Any, Callable

from mrta_zenoh import keys
from mrta_zenoh.fieldpath import FieldPathError
from mrta_zenoh.messages import GenericMessage
from mrta_zenoh.untrusted import visible

from .holders import SampleHolder
from .monitors import Monitor, group_reader
from .strangers import MAX_NAME, Strangers

log = logging.getLogger("mrta.supervisor")
Apply = Callable[[dict[str, str], str, float], "list[SampleHolder] | None"]
MAX_IDS = 10_000   # raw id texts memoised
MAX_CACHED = 10_000  # keys in the hot path's cache (keys come from the network: bounded)


class Ids:
    """Ids from the network, checked (one key chunk, ≤ 64 characters; robot ids lose a
    leading `/`) and memoised, as ids repeat: `ids(raw)` is the id, or None."""

    def __init__(self) -> None:
        self.memo: dict[str, str | None] = {}  # raw id text → normalised id (None: invalid)

    def __call__(self, raw: str) -> str | None:
        out = self.memo.get(raw, False)
        if out is False:
            rid = raw.strip().strip("/")
            out = rid if keys.is_id(rid) else None
            if len(self.memo) >= MAX_IDS:
                self.memo.clear()
            self.memo[raw] = out
        return out


class Intake:
    def __init__(self, ids: Ids, robots: dict, counts: dict[str, int], strangers: Strangers,
                 apply: Apply, lock: threading.Lock, logger: logging.Logger = log):
        """`apply(values, key, now)`: the supervisor takes a reading (role → id) in, under
        `lock`; it returns the holders the sample keeps high (None: it used nothing)."""
        self.ids, self.robots, self.counts, self.strangers = ids, robots, counts, strangers
        self._apply, self._lock = apply, lock
        self._fast: dict[str, tuple] = {}      # key → (type, field values, holders) last accepted
        self._ingest: dict[int, tuple] = {}    # id(monitor group) → (group, ingest)
        self._warned: set[tuple[str, str]] = set()
        self._log = logger

    def forget(self) -> None:
        """Drop the hot path's cache (a new run: nothing held may be taken as still high)."""
        self._fast.clear()

    def ingest_fn(self, monitors: list[Monitor]):
        """`ingest(key, type_name, message, now)` for one group of monitors (`now` a callable,
        read once the fields are read)."""
        cached = self._ingest.get(id(monitors))
        if cached is not None and cached[0] is monitors:  # the group is kept: its id stays its own
            return cached[1]
        read = group_reader(monitors)
        fast, lock, counts, full = self._fast, self._lock, self.counts, self.full

        def ingest(key: str, type_name: str, message: Any, now: Callable[[], float]) -> None:
            vals = None
            if read is not None and type(message) is not GenericMessage:
                try:
                    vals = read(message)
                except AttributeError:
                    pass
            t = now()
            with lock:
                if vals is not None:
                    hit = fast.get(key)
                    if hit is not None and hit[0] == type_name and hit[1] == vals:
                        for h in hit[2]:
                            if not h.high:
                                break
                            h.last, h.until = t, t + h.timeout
                        else:
                            counts["samples"] += 1
                            return
                full(monitors, key, type_name, message, t, vals)

        self._ingest[id(monitors)] = (monitors, ingest)
        return ingest

    def full(self, monitors: list[Monitor], key: str, type_name: str, message: Any,
             now: float, vals) -> None:
        """The full path, under the lock: read, check, apply, cache."""
        self.counts["samples"] += 1
        if monitors[0].by_sender and not self._sender_known(key, now):
            return
        values = self.read(monitors, type_name, message)
        if values is None:
            return
        robot = values.get("busy_robots") or values.get("idle_robots")
        if robot is not None and monitors[0].by_sender and robot != keys.first_chunk(key):
            self.counts["key_mismatch"] += 1
            return
        held = self._apply(values, key, now)
        if vals is not None and held:
            if len(self._fast) >= MAX_CACHED:
                self._fast.clear()
            self._fast[key] = (type_name, vals, tuple(held))

    def _sender_known(self, key: str, now: float) -> bool:
        """Who sent it comes first: a stranger is a stranger, whatever its fields say."""
        sender = self.ids(keys.first_chunk(key))
        if sender is None:
            self.counts["bad_keys"] += 1
            return False
        if sender not in self.robots:
            self.strangers.heard("robot", sender, now)
            return False
        return True

    def read(self, monitors: list[Monitor], type_name: str, message: Any) -> dict | None:
        """role → id, for every monitor of the group; None (counted) if any fails."""
        values: dict[str, str] = {}
        for m in monitors:
            if type_name != m.topic.type:
                self.counts["wrong_type"] += 1
                self._warn_type(m, type_name)
                return None
            try:
                value = m.path.get(message)
            except FieldPathError:
                self.counts["field_errors"] += 1
                return None
            if type(value) is not str:
                if not isinstance(value, (int, float)) or isinstance(value, bool):
                    self.counts["field_errors"] += 1
                    return None
                value = str(value)
            ident = self.ids(value)
            if ident is None:  # not an id: a sample is used whole or not at all
                self.counts["field_errors"] += 1
                return None
            values[m.role] = ident
        return values

    def _warn_type(self, m: Monitor, type_name: str) -> None:
        shown = visible(type_name, MAX_NAME)
        if (m.key_expr, shown) not in self._warned and len(self._warned) < 1000:
            self._warned.add((m.key_expr, shown))
            self._log.warning("%s: ignoring samples of type %s (the architecture says %s)",
                        m.key_expr, shown, m.topic.type)
