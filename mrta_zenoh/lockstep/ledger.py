"""The barrier's ledger: each participant's last answer, the largest claim per key over them, and
what one participant may claim (docs/security.md, "Lockstep and the clock").

Why caps. Every step carries every claim to every participant, so one participant's claims are
everybody's problem: 4,096 keys of its own (or 4,000 keys of 1 KB, a Step past the 4 MiB a
sample may have) would make every Step one the participants refuse, and the fleet would stand
still while the claimant holds its token — on a secured fleet too, with one robot's own
certificate. So a participant's claims are bounded by what its role may publish: keys under
its own name only
(a secured fleet's access control lets robotN publish under `robotN/**` only, and an honest agent
publishes nowhere else on an open bus either), at most CLAIM_KEYS keys of CLAIM_KEY_CHARS
characters, CLAIM_CHARS in all, and only as long as the run's key table has room (MAX_KEYS, first
come first served). A StepDone over a cap still answers the step: its claims are dropped —
counted, logged, and once per participant and run counted as forgiven (the run is then
inexact) — and the Steps stay what the other participants can read.

An agent host answers for several robots (protocol.SPEAKS): its claims may be under each of
their names too, and its caps grow with them (one robot's caps per name), so a host of K robots
claims what K processes would. Whoever may declare a speaks token may claim under that robot's
name: on an open bus that is anybody, who could publish under the name anyway; a secured fleet's
access control grants a robot its own participant token only, so there nobody speaks for
another (and agent hosts refuse secured fleets).
"""

from __future__ import annotations

from .protocol import (CLAIM_CHARS, CLAIM_KEY_CHARS, CLAIM_KEYS, MAX_KEYS, MAX_NAMES,
                       MAX_SPEAKS_FOR, StepDone)


class Ledger:
    """`done`: participant → its last StepDone (claims within the caps); `claims`: key → the
    largest count in `done`, kept up to date per answer (100 participants answer every step)."""

    def __init__(self) -> None:
        self.done: dict[str, StepDone] = {}
        self.claims: dict[str, int] = {}
        self.capped: set[str] = set()  # participants whose claims were dropped in this run
        self.voices: dict[str, set[str]] = {}  # participant → robots it answers for (SPEAKS)

    def speaks_for(self, name: str, robot: str, alive: bool) -> bool:
        """`name`'s token saying it answers for `robot` came (or went); False if refused (too
        many names, or too many robots for one participant: a flood costs bounded memory)."""
        if not alive:
            robots = self.voices.get(name)
            if robots is not None:
                robots.discard(robot)
                if not robots:
                    del self.voices[name]
            return True
        robots = self.voices.get(name)
        if robots is None:
            if len(self.voices) >= MAX_NAMES:
                return False
            robots = self.voices[name] = set()
        if robot not in robots and len(robots) >= MAX_SPEAKS_FOR:
            return False
        robots.add(robot)
        return True

    def names_of(self, name: str) -> set[str]:
        """The names `name` may claim under: its own and those of the robots it answers for."""
        return {name, *self.voices.get(name, ())}

    def over_cap(self, name: str, sent: dict[str, int], own) -> str | None:
        """Why `name` may not claim `sent` (None: it may). `own`: the keys the simulator
        publishes itself — its own count is theirs, whoever claims them."""
        names = self.names_of(name)
        scale = len(names)
        if len(sent) > CLAIM_KEYS * scale:
            return f"{len(sent)} keys (at most {CLAIM_KEYS * scale})"
        chars = 0
        for key in sent:
            if key.split("/", 1)[0] not in names or "/" not in key:
                return f"{key[:80]!r} is not under its own name"
            if len(key) > CLAIM_KEY_CHARS:
                return f"a key of {len(key)} characters (at most {CLAIM_KEY_CHARS})"
            chars += len(key)
        if chars > CLAIM_CHARS * scale:
            return f"keys of {chars} characters in all (at most {CLAIM_CHARS * scale})"
        new = sum(k not in self.claims and k not in own for k in sent)
        if new and len(self.claims) + new + len(own) > MAX_KEYS:
            return f"the run's key table is full ({MAX_KEYS} keys)"
        return None

    def answer(self, name: str, d: StepDone) -> StepDone | None:
        """`d` is `name`'s answer now; the one it replaces."""
        prev = self.done.get(name)
        self.done[name] = d
        self._claim(prev, d)
        return prev

    def forget(self, name: str) -> None:
        """`name` is gone: its claims no longer count."""
        gone = self.done.pop(name, None)
        if gone is not None:
            self._recount(k for k, n in gone.sent.items() if self.claims.get(k) == n)

    def _claim(self, prev: StepDone | None, d: StepDone) -> None:
        """Keep `claims` the per-key maximum over `done` after `prev` became `d` (counts only
        grow in an honest run; a lower one may take the maximum down: those keys are counted
        again over every participant)."""
        claims, lowered = self.claims, []
        old = prev.sent if prev is not None else {}
        for k, n in d.sent.items():
            top = claims.get(k)
            if top is None or n > top:
                claims[k] = n
            elif n < top and old.get(k) == top:
                lowered.append(k)
        if old:
            lowered.extend(k for k in old.keys() - d.sent.keys() if claims.get(k) == old[k])
        if lowered:
            self._recount(lowered)

    def _recount(self, keys) -> None:
        for k in list(keys):
            counts = [d.sent[k] for d in self.done.values() if k in d.sent]
            if counts:
                self.claims[k] = max(counts)
            else:
                self.claims.pop(k, None)
