"""The agent's inbox: teammates' coordination messages between the network callbacks that
queue them and the loop thread that hands them to the decision logic (robot_agent/runtime/
loop.py), and the one rule for when something heard is due (`is_due`), which the fault
injector's drop count follows too (faults.py)."""

from __future__ import annotations

import collections
from typing import NamedTuple

from mrta_zenoh.clock import EPSILON
from mrta_zenoh.messages import Message

INBOX = 10_000  # queued messages at most: a flood drops the oldest, never grows the process


def is_due(heard: float, now: float, lockstep: bool, delayed: bool) -> bool:
    """Whether what counts as heard at `heard` is handled at `now` (`Inbox.take_due`)."""
    return not ((lockstep and heard >= now) or (delayed and heard > now + EPSILON))


class Heard(NamedTuple):
    """One queued message: when it counts as heard (its stamp in lockstep, else its arrival;
    plus an injected latency), its kind, its sender, the message and the key it came on."""

    at: float
    kind: str
    sender: str
    message: Message
    key: str

    def order(self) -> tuple:
        """The lockstep order (`Inbox.take_due`): time heard, sender, key, sequence number."""
        return self.at, self.sender, self.key, self.message.header.seq


class Inbox:
    """Bounded: network callbacks `put` (a deque's append is atomic), the loop thread alone
    takes. A flood drops the oldest, so the process never grows."""

    def __init__(self, size: int = INBOX):
        self._items: collections.deque[Heard] = collections.deque(maxlen=size)

    def __len__(self) -> int:
        return len(self._items)

    def put(self, item: Heard) -> None:
        self._items.append(item)

    def clear(self) -> None:
        self._items.clear()

    def take_due(self, now: float, lockstep: bool, delayed: bool) -> list[Heard]:
        """Every queued item due at `now`. In lockstep, one stamped at this very time waits for
        the next tick: the sender handled this step too, and what it said belongs after it.
        One delayed by an injected latency (`delayed`) waits until its time (and they come in
        time order: jitter reorders messages, as a network does).

        In lockstep the items due are put in (time heard, sender, key, sequence number) order:
        the order they arrived in is the network's — even one teammate's, on two keys — and it
        changed what a run did: which of two announcements stamped alike was bid on first,
        hence the bids' sequence numbers, hence which bid an injected loss drew."""
        due, later = [], []
        while self._items:
            item = self._items.popleft()
            (due if is_due(item.at, now, lockstep, delayed) else later).append(item)
        self._items.extendleft(reversed(later))
        if lockstep:
            due.sort(key=Heard.order)
        elif delayed:
            due.sort(key=lambda item: item.at)
        return due
