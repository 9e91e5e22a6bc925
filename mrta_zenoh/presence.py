"""Which robots are up, from liveliness tokens: a robot is up while any token under `robotN/**`
is alive (its agent, a sensor node — whichever declares one). What the simulator waits for
before its clock starts (`mrta sim --wait-robots`) and what a mission waits for before it runs.
`@` keys (the clock source, the recorder, lockstep) are matched by no wildcard, so infrastructure
never counts as a robot."""

from __future__ import annotations

import threading

from .keys import first_chunk
from .lifecycle import Closing


class RobotPresence(Closing):
    def __init__(self, bus, robot_ids: list[str]):
        self._tokens: dict[str, set[str]] = {r: set() for r in robot_ids}
        self._seen: set[str] = set()  # robots that have been up
        self._lock = threading.Lock()
        self.changed = threading.Event()  # set on every change of a known robot's tokens
        self._watch = bus.watch_liveliness("**", self._on_token)

    def _on_token(self, key: str, up: bool) -> None:
        rid = first_chunk(key)
        with self._lock:
            tokens = self._tokens.get(rid)
            if tokens is None:
                return
            (tokens.add if up else tokens.discard)(key)
            if up:
                self._seen.add(rid)
        self.changed.set()

    def missing(self) -> list[str]:
        with self._lock:
            return [r for r, tokens in self._tokens.items() if not tokens]

    def gone(self) -> list[str]:
        """Robots that were up and are not: their processes went (a crash, a cut). A robot
        that never had a token — driven by a script that declares none — is not gone."""
        with self._lock:
            return [r for r, tokens in self._tokens.items() if r in self._seen and not tokens]

    def all_up(self) -> bool:
        return not self.missing()

    def close(self) -> None:
        self._watch.close()

