"""An in-process bus for fast deterministic unit tests and single-process runs.

Several `InProcBus` objects may share one `InProcNetwork`, each standing for a process: closing
one removes its liveliness tokens exactly as a process exit does on Zenoh. Delivery is
synchronous (publish returns after every handler ran), which is what makes tests deterministic.
"""

from __future__ import annotations

import threading
from typing import Callable, Iterable

from ..keys import matches
from ..lifecycle import Closing
from .base import Bus, LivelinessWatch, Subscription, Token


class InProcNetwork:
    def __init__(self) -> None:
        self.lock = threading.RLock()
        self.subs: list[Subscription] = []
        self.watches: list[LivelinessWatch] = []
        self.tokens: list[Token] = []
        self.queryables: list[_Queryable] = []


class _Queryable(Closing):
    def __init__(self, bus: "InProcBus", key: str, answer: Callable[[], list[tuple[str, bytes]]]):
        self.bus, self.key, self.answer = bus, key, answer

    def close(self) -> None:
        with self.bus.network.lock:
            if self in self.bus.network.queryables:
                self.bus.network.queryables.remove(self)


class InProcBus(Bus):
    def __init__(self, network: InProcNetwork | None = None, namespace: str = ""):
        super().__init__(namespace)
        self.network = network or InProcNetwork()

    def publish_raw(self, key: str, encoding: str, payload: bytes, lossy: bool = False) -> None:
        counts = self._counts
        if counts is not None and not key.startswith("@"):  # lockstep's own keys: not counted
            counts.sent[key] += 1
        wire = self._wire(key)
        with self.network.lock:
            targets = [s for s in self.network.subs if matches(s.bus._wire(s.key_expr), wire)]
        for s in targets:
            s._dispatch(s.bus._local(wire), encoding, payload)

    def _declare(self, sub: Subscription) -> None:
        with self.network.lock:
            self.network.subs.append(sub)
        self._subs.append(sub)

    def _undeclare(self, sub: Subscription) -> None:
        with self.network.lock:
            if sub in self.network.subs:
                self.network.subs.remove(sub)

    def _declare_token(self, tok: Token) -> None:
        wire = self._wire(tok.key)
        with self.network.lock:
            self.network.tokens.append(tok)
            watches = [w for w in self.network.watches if matches(w.bus._wire(w.key_expr), wire)]
        self._tokens.append(tok)
        for w in watches:
            w._event(w.bus._local(wire), True)

    def _undeclare_token(self, tok: Token) -> None:
        wire = self._wire(tok.key)
        with self.network.lock:
            if tok not in self.network.tokens:
                return
            self.network.tokens.remove(tok)
            still = any(t.bus._wire(t.key) == wire for t in self.network.tokens)
            watches = [w for w in self.network.watches if matches(w.bus._wire(w.key_expr), wire)]
        if not still:
            for w in watches:
                w._event(w.bus._local(wire), False)

    def _declare_watch(self, w: LivelinessWatch, history: bool) -> None:
        with self.network.lock:
            self.network.watches.append(w)
            current = sorted({t.bus._wire(t.key) for t in self.network.tokens
                              if matches(self._wire(w.key_expr), t.bus._wire(t.key))})
        self._watches.append(w)
        if history:
            for key in current:
                w._event(self._local(key), True)

    def _undeclare_watch(self, w: LivelinessWatch) -> None:
        with self.network.lock:
            if w in self.network.watches:
                self.network.watches.remove(w)

    def _declare_queryable(self, key: str,
                           answer: Callable[[], list[tuple[str, bytes]]]) -> Closing:
        q = _Queryable(self, key, answer)
        with self.network.lock:
            self.network.queryables.append(q)
        return q

    def _query(self, key_expr: str, timeout: float) -> Iterable[tuple[str, str, bytes]]:
        wire = self._wire(key_expr)
        with self.network.lock:
            found = [q for q in self.network.queryables
                     if not q.bus.closed and matches(wire, q.bus._wire(q.key))]
        for q in found:
            for encoding, payload in q.answer():
                yield self._local(q.bus._wire(q.key)), encoding, payload
