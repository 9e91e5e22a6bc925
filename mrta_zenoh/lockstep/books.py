"""A process's lockstep books: what it received of what the others say they sent, less what is
known lost (forgiven)."""

from __future__ import annotations

import itertools
import operator
import time
from array import array
from typing import Callable

from ..keys import matches
from .protocol import FORGIVE_WINDOW, MAX_IN_FLIGHT, MAX_KEYS, MAX_NAMES
from .table import WORD, Claims, KeyTable

_COUNTED, _IGNORED = b"\xff" * WORD, bytes(WORD)  # a table index's word in Books' mask


class Books:
    """What this process received of what the others say they sent, less what is known lost.

    Counts are cumulative per key. A sample that will never arrive (its link was down; a forged
    claim) would hold every later step for ever: `forgive` records it as an offset, so only the
    one step waits (at most count_wait), and the next ones count from there.

    One pause per claimant per FORGIVE_WINDOW. A key's claimant is its first chunk: a
    participant's claims count only under its own name (the barrier drops the others, as a
    secured fleet's access control drops what a robot publishes elsewhere). Once a claimant's
    claims were forgiven, its unmet claims are forgiven without waiting for FORGIVE_WINDOW
    (`at_once`): a claim that keeps changing — lowered to withdraw a forgiveness, or raised
    past it — cannot pause the run again and again (a claim lowered by 1 every 5.2 s would
    otherwise pause the fleet 8 times in 45 s, at 6 % of its speed). The price, in a run that
    is inexact anyway: for that window this process does not wait for that claimant's samples
    in flight either.

    Cost. A step claims every key of the run — with 100 robots about 1,100 — and a
    participant looks at its claims once per step; most keys are none of its subscriptions',
    and of those that are (a teammate's broadcast, its log) few changed since the last step. A
    loop over its few hundred keys in Python is half of a patrol agent's CPU with 100 agents on
    2 cores (py-spy, GIL samples; caches are cold with 100 processes). So which subscriptions
    count a key is worked out once per key (again when the bus's subscriptions change), and
    which table indices each subscription counts once per table entry; claims and counts are
    then compared per subscription in C (`map` and `compress` over the lists' and dicts' own
    methods): Python sees only the keys that lag behind.

    And most steps need not even that: once a step is taken (`settle`), every claim it made
    has arrived or been forgiven, and within a run counts and offsets only grow — so at the
    next step only the claims that changed can lag. Which of this participant's keys changed is
    one XOR of the two steps' packed counts, masked by the words its subscriptions count (big
    integers: C over a few kB); Python then looks at those keys only (100 agents: a dozen or so
    a step, against a few hundred compared before). A withdrawn forgiveness lowers an offset,
    but only for a key whose claim went down, which is then among those that changed. Anything
    else that voids the argument — other subscriptions, another table, a new run — falls back
    to the comparison over every key."""

    MEMO = 4 * MAX_KEYS  # keys remembered; beyond, the memory starts again

    def __init__(self, counts, wall: Callable[[], float] = time.monotonic) -> None:
        self.counts = counts                      # the bus's (Bus.enable_counting)
        self._wall = wall
        self._excused: dict[str, float] = {}      # claimant → wall time its window closes
        self.offsets: dict[str, int] = {}
        self._forgiven: dict[str, tuple[int, int]] = {}  # key → (claim forgiven, offset before)
        self.lost = 0
        self._subs: tuple = ()                    # the subscriptions' tallies the memo is for
        self._matching: dict[str, tuple] = {}     # key → the tallies matching it
        self._unmatched: set[str] = set()         # keys of `_matching` no subscription counts
        self._table: KeyTable | None = None       # the table `_indices` is for …
        self._generation = -1                     # … in this generation
        self._learned = 0                         # … up to this entry
        self._indices: dict = {}                  # tally → ([table index], [key])
        self._words = bytearray()                 # per table index: 8 × 0xff if counted
        self._mask = 0                            # … as one integer
        # the claims of the step last taken: (table, generation, subscriptions, counts)
        self._settled: tuple | None = None
        self._looked: tuple = ()                  # the subscriptions the last whole look was for

    def _counting(self, table: KeyTable | None = None) -> dict[str, tuple]:
        """key → the matching subscriptions' tallies, valid for the bus's subscriptions now
        (and `_indices` for `table`)."""
        subs = self.counts.tallies()
        if subs != self._subs or len(self._matching) > self.MEMO:
            self._subs = subs
            self._matching = {}
            self._unmatched = set()
            self._table = None
        if table is not None and (table is not self._table or
                                  table.generation != self._generation):
            self._table, self._generation, self._learned = table, table.generation, 0
            self._indices = {s: ([], []) for s in self._subs}
            self._words, self._mask = bytearray(), 0
        return self._matching

    def _subs_of(self, matching: dict[str, tuple], key: str) -> tuple:
        subs = matching.get(key)
        if subs is None:
            subs = matching[key] = tuple(s for s in self._subs if matches(s.key_expr, key))
            if not subs:
                self._unmatched.add(key)
        return subs

    def _received(self, matching: dict[str, tuple], key: str) -> int | None:
        """Samples on `key` every subscription of this bus matching it has taken into account
        (None: no subscription matches, nothing to wait for)."""
        subs = self._subs_of(matching, key)
        if not subs:
            return None
        return min(s.counts[key] for s in subs)

    def missing(self, required: Claims, keys=None) -> dict[str, int]:
        """Key → samples claimed that have not arrived (keys no subscription of this bus
        counts are never waited for). A key this bus publishes itself is waited for up to what
        it sent, heard back by its own subscriptions (a robot's ReportDue hearing its own
        report): were they handed over on another thread, the tick that first sees one would
        depend on thread scheduling — two runs of one seed ended robot3's report 0.1 s apart
        under load when Zenoh delivered them. ZenohBus hands them over before publish()
        returns, so this wait is met at once there; it stays for a bus that does not (the
        Bus contract does not promise it). `keys`: look only at
        these (those found missing before: counts only grow, so the others still have
        arrived)."""
        own = self.counts.sent
        matching = self._counting(required.table)
        if keys is None:
            keys = self._lagging(matching, required, own)
        offsets = self.offsets
        out = {}
        for key in keys:
            got = self._received(matching, key)
            need = own[key] if key in own else required.get(key)
            if got is None or need is None:
                continue
            gap = need - got - offsets.get(key, 0)
            if gap > 0:
                out[key] = gap
        return out

    def _lagging(self, matching: dict[str, tuple], required: Claims,
                 own: dict[str, int]) -> set[str]:
        """The keys that may lag: those some subscription has counted less of (plus its
        offset) than claimed, found per subscription in C, and every key this bus sent that a
        subscription of its own counts (its claim is what it sent: `missing` decides those one
        by one). A superset of what is missing."""
        table = required.table
        self._looked = self._subs
        if self._learned < len(table):
            words = self._words
            for i in range(self._learned, len(table)):
                key = table.keys[i]
                subs = self._subs_of(matching, key)
                words += _COUNTED if subs else _IGNORED
                for s in subs:
                    indices, keys = self._indices[s]
                    indices.append(i)
                    keys.append(key)
            self._learned = len(table)
            self._mask = int.from_bytes(words, "little")
        if not own.keys() <= matching.keys():  # in C
            for key in own.keys() - matching.keys():
                self._subs_of(matching, key)
        zeros = itertools.repeat(0)
        counts, offsets = required.counts, self.offsets
        out = set(own.keys() - self._unmatched)
        settled = self._settled
        if settled is not None and settled[0] is table and settled[1] == table.generation \
                and settled[2] is self._subs and len(settled[3]) <= len(counts):
            changed = (int.from_bytes(counts, "little") ^
                       int.from_bytes(settled[3], "little")) & self._mask
            if changed:
                words = array("Q")
                words.frombytes(changed.to_bytes(len(counts) * WORD, "little"))
                keys = table.keys
                for i in itertools.compress(range(len(words)), words):
                    key = keys[i]
                    claim = counts[i] - offsets.get(key, 0)
                    if any(claim > s.counts.get(key, 0) for s in matching[key]):
                        out.add(key)
            return out
        for sub, (indices, keys) in self._indices.items():
            claimed = map(counts.__getitem__, indices)
            counted = map(sub.counts.get, keys, zeros)
            if offsets:
                counted = map(operator.add, counted, map(offsets.get, keys, zeros))
            out.update(itertools.compress(keys, map(operator.gt, claimed, counted)))
        return out

    def settle(self, taken: Claims) -> None:
        """`taken`'s claims have all arrived or been forgiven (its step was taken): the next
        look compares with them (only what changed since can lag)."""
        self._settled = (taken.table, taken.table.generation, self._looked, taken.counts)

    def at_once(self, missing: dict[str, int]) -> dict[str, int]:
        """Of `missing`, what is forgiven without waiting: a gap no process has in flight
        (MAX_IN_FLIGHT), or one whose claimant's claims were forgiven within FORGIVE_WINDOW."""
        if not self._excused:
            return {k: n for k, n in missing.items() if n > MAX_IN_FLIGHT}
        now, excused = self._wall(), self._excused
        return {k: n for k, n in missing.items()
                if n > MAX_IN_FLIGHT or excused.get(claimant(k), now) > now}

    def forgive(self, missing: dict[str, int], required: Claims) -> bool:
        """Forgive `missing`; True if a claimant of it was not excused yet (this forgiveness is
        news: the caller counts and logs it), whose window then opens."""
        now, excused, news = self._wall(), self._excused, False
        for key, gap in missing.items():
            before = self.offsets.get(key, 0)
            claim = required.get(key)
            if claim is not None:  # not so a key of its own nobody claimed: no claim to review
                self._forgiven[key] = (claim, before)
            self.offsets[key] = before + gap
            self.lost += gap
            who = claimant(key)
            if excused.get(who, now) <= now:
                news = True
                if len(excused) >= MAX_NAMES:  # bounded: the closed windows go first
                    for gone in [c for c, until in excused.items() if until <= now]:
                        del excused[gone]
                if len(excused) < MAX_NAMES:
                    excused[who] = now + FORGIVE_WINDOW
        return news

    def review(self, required: Claims) -> list[str]:
        """Withdraw forgiveness a later, lower claim shows to have been forged (legitimate counts
        only grow within a run); the keys it was withdrawn for."""
        withdrawn = []
        for key, (claim, before) in list(self._forgiven.items()):
            now = required.get(key)
            if now is not None and now < claim:
                self.offsets[key] = before
                del self._forgiven[key]
                withdrawn.append(key)
        return withdrawn

    def reset(self) -> None:
        """A new run: counts start again from zero, sent and received."""
        self.counts.reset()
        self.offsets.clear()
        self._forgiven.clear()
        self._excused.clear()
        self._settled = None


def claimant(key: str) -> str:
    """Who may claim `key`: its first chunk (a robot speaks under `robotN/`)."""
    return key.split("/", 1)[0]

