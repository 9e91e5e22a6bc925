"""What a bus counts for lockstep (mrta_zenoh.lockstep): samples it published, per key, and per
subscription the samples each has taken into account, per key.

The bus owns the increments — they are on the hot path of every sample (100 agents in
lockstep), so the implementations do them inline — and lockstep owns the reading: its books
compare these counts with what a step claims. `Bus.enable_counting(on_counted)` turns counting
on once, for one owner, and gives this object; nothing is counted before (a bus that is no
lockstep participant pays one `is None` test per sample); `close()` turns it off again (the
owner is done: another may count from zero).
"""

from __future__ import annotations

import collections
from typing import Callable

from ..lifecycle import Closing


def _nothing() -> None:
    pass


class Tally:
    """One subscription's counts: `counts[key]`, samples on `key` it has taken into account
    (after its handler ran; for a queued subscription, once queued). `counted` is the owner's
    on-counted callback, called after each increment."""

    __slots__ = ("key_expr", "counts", "counted")

    def __init__(self, key_expr: str, counted: Callable[[], None]) -> None:
        self.key_expr = key_expr
        self.counts: collections.Counter[str] = collections.Counter()
        self.counted = counted


class Counts(Closing):
    """A bus's counts, read by lockstep. `sent[key]`: samples this bus published on `key` (keys
    starting with `@` — lockstep's own traffic — are not counted); `tallies()`: the counting
    subscriptions as they are now (decoded ones: raw subscriptions count nothing)."""

    def __init__(self, bus, on_counted: Callable[[], None] | None) -> None:
        self.sent: collections.Counter[str] = collections.Counter()
        self._bus = bus  # its subscriptions: tallies() follows them
        self._counted = on_counted or _nothing

    def claims(self) -> dict[str, int]:
        """What this bus claims in a lockstep answer: `sent`, less the keys left unclaimed
        (Bus.leave_unclaimed: monitoring nobody in the run waits for)."""
        unclaimed = self._bus._unclaimed
        if not unclaimed:
            return dict(self.sent)
        return {k: n for k, n in self.sent.items() if k not in unclaimed}

    def tally(self, key_expr: str) -> Tally:
        """A new subscription's tally (the bus attaches it)."""
        return Tally(key_expr, self._counted)

    def tallies(self) -> tuple[Tally, ...]:
        """The tallies of the bus's subscriptions now, in their order: lockstep's books remember
        which of them match each key, and start again when this changes."""
        return tuple(t for t in (s._tally for s in list(self._bus._subs)) if t is not None)

    def received(self, sub) -> collections.Counter[str]:
        """`sub`'s per-key counts (a subscription of this bus)."""
        if sub._tally is None:
            raise ValueError(f"the subscription to {sub.key_expr!r} counts nothing (a raw one)")
        return sub._tally.counts

    def reset(self) -> None:
        """Start again from zero, sent and received (lockstep: a new run)."""
        self.sent.clear()
        for t in self.tallies():
            t.counts.clear()

    def close(self) -> None:
        """Stop counting on the bus (its owner is done with it)."""
        self._bus._stop_counting(self)

