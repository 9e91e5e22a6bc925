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
"""

from __future__ import annotations

from .protocol import CLAIM_CHARS, CLAIM_KEY_CHARS, CLAIM_KEYS, MAX_KEYS, StepDone


class Ledger:
    """`done`: participant → its last StepDone (claims within the caps); `claims`: key → the
    largest count in `done`, kept up to date per answer (100 participants answer every step)."""

    def __init__(self) -> None:
        self.done: dict[str, StepDone] = {}
        self.claims: dict[str, int] = {}
        self.capped: set[str] = set()  # participants whose claims were dropped in this run

    def over_cap(self, name: str, sent: dict[str, int], own) -> str | None:
        """Why `name` may not claim `sent` (None: it may). `own`: the keys the simulator
        publishes itself — its own count is theirs, whoever claims them."""
        if len(sent) > CLAIM_KEYS:
            return f"{len(sent)} keys (at most {CLAIM_KEYS})"
        prefix, chars = name + "/", 0
        for key in sent:
            if not key.startswith(prefix):
                return f"{key[:80]!r} is not under its own name"
            if len(key) > CLAIM_KEY_CHARS:
                return f"a key of {len(key)} characters (at most {CLAIM_KEY_CHARS})"
            chars += len(key)
        if chars > CLAIM_CHARS:
            return f"keys of {chars} characters in all (at most {CLAIM_CHARS})"
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
