"""The team as the agent's liveliness tokens tell it: what the network callbacks heard of
teammates' agent (or process) tokens and subject tokens, and what the loop thread has told the
coordinator of them.

Kept out of the driver (loop.py) because it is one responsibility with its own thread rule:
callbacks on the network's threads only record the latest state per robot (and per robot and
subject) under a lock, apart from the bounded inbox, so a flood of messages can never push a
teammate out of the team; the loop thread alone takes the changes at its next tick and applies
them in sorted order, not the network's. Which token is an outsider's (the roster) and what a
refused one costs stay with the driver, which counts every refusal in one place.
"""

from __future__ import annotations

import threading
from typing import Iterator

MAX_TOKENS = 1_000  # robots whose tokens are tracked: invented ids beyond are ignored, counted
MAX_SUBJECT_TOKENS = 10_000  # teammates' subject tokens tracked: a flood beyond is ignored, counted


class TeamTokens:
    """Teammates' tokens: `alive` is the callbacks' view (for dropping strangers' messages
    before they take inbox space); `take` hands the loop what changed since it last asked."""

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self.alive: set[str] = set()
        self.ignored = 0  # tokens beyond MAX_TOKENS / MAX_SUBJECT_TOKENS
        self._changes: dict[str, bool] = {}
        self._subject_changes: dict[tuple[str, str], bool] = {}
        self._subject_seen: set[tuple[str, str]] = set()  # callbacks' view (MAX_SUBJECT_TOKENS)
        # the loop's side: who holds which subject token (live tokens whatever the team) and
        # what the coordinator was told (only robots in the team)
        self._subject_tokens: dict[str, set[str]] = {}
        self.told_subjects: dict[str, set[str]] = {}

    # ------------------------------------------------------------ network callbacks
    def record(self, robot: str, alive: bool) -> None:
        """A teammate's agent token (or a process's token) came or went."""
        with self._lock:
            if alive and robot not in self.alive and len(self.alive) >= MAX_TOKENS:
                self.ignored += 1
                return
            (self.alive.add if alive else self.alive.discard)(robot)
            self._changes[robot] = alive

    def record_subject(self, robot: str, subject: str, alive: bool) -> None:
        """A teammate's subject token came or went."""
        pair = (robot, subject)
        with self._lock:
            if alive and pair not in self._subject_seen:
                if len(self._subject_seen) >= MAX_SUBJECT_TOKENS:
                    self.ignored += 1
                    return
                self._subject_seen.add(pair)
            elif not alive:
                self._subject_seen.discard(pair)
            self._subject_changes[pair] = alive

    def hears_alive(self, robot: str) -> bool:
        """Whether `robot`'s token is alive as the callbacks heard it."""
        with self._lock:
            return robot in self.alive

    def missing(self, roster: frozenset[str], own: str) -> list[str]:
        """The robots on `roster` (but `own`) whose token has not come, sorted."""
        with self._lock:
            return sorted(roster - self.alive - {own})

    # ------------------------------------------------------------ the loop thread
    def take(self) -> tuple[dict[str, bool], dict[tuple[str, str], bool]]:
        """What changed since the last call: agent tokens by robot, subject tokens by pair."""
        with self._lock:
            changes, self._changes = self._changes, {}
            subject_changes, self._subject_changes = self._subject_changes, {}
        return changes, subject_changes

    def subjects_to_tell(self, robots: set[str], changes: dict[tuple[str, str], bool],
                         team: set[str]) -> Iterator[tuple[str, str, bool]]:
        """What the coordinator must be told of `robots`' subjects, (robot, subject, held): a
        subject counts while its token lives and its robot is on the team (holds its agent
        token) — one whose agent token comes later counts from then, and all of a robot's go
        with its agent token. Remembers what it yields as told."""
        for (robot, subject), alive in sorted(changes.items()):
            held = self._subject_tokens.setdefault(robot, set())
            (held.add if alive else held.discard)(subject)
            if not held:
                del self._subject_tokens[robot]
        for robot in sorted(robots):
            want = self._subject_tokens.get(robot, set()) if robot in team else set()
            told = self.told_subjects.get(robot, set())
            for subject in sorted(told - want):
                yield robot, subject, False
            for subject in sorted(want - told):
                yield robot, subject, True
            if want:
                self.told_subjects[robot] = set(want)
            else:
                self.told_subjects.pop(robot, None)
