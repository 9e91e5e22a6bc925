"""Sample holders and the transition history (rqt_mrta's SampleHolder, StateMonitor and History).

A holder is "high" from a sample until `timeout` seconds after the latest one. It reports rising
edges when a sample arrives and falling edges when someone asks at or after the expiry; `expiry`
lets the caller sleep exactly until the next falling edge instead of polling.
"""

from __future__ import annotations

import collections
from dataclasses import dataclass


class SampleHolder:
    __slots__ = ("timeout", "until", "last", "high", "value")

    def __init__(self, timeout: float):
        if timeout <= 0:
            raise ValueError(f"timeout must be positive, got {timeout}")
        self.timeout = timeout
        self.until = float("-inf")
        self.last = float("-inf")
        self.high = False
        self.value: object = None

    def sample(self, now: float, value: object = None) -> bool:
        """Record a sample; True on a rising edge."""
        self.last = now
        self.until = now + self.timeout
        self.value = value
        if not self.high:
            self.high = True
            return True
        return False

    def update(self, now: float) -> bool:
        """True on a falling edge (the timeout elapsed since the last sample)."""
        if self.high and now >= self.until:
            self.high = False
            return True
        return False

    def drop(self) -> bool:
        """Force low (e.g. the robot went offline); True if it was high."""
        was = self.high
        self.high = False
        self.until = float("-inf")
        return was


@dataclass(frozen=True)
class StateChange:
    time: float
    kind: str       # robot | task | allocation | alarm | run
    subject: str    # robot id, task id, "task->robot", alarm subject, "clock"
    old: str
    new: str

    def to_json(self) -> dict:
        return {"time": self.time, "kind": self.kind, "subject": self.subject,
                "from": self.old, "to": self.new}


class History:
    """Every transition with its time; bounded so a week-long run does not grow without end."""

    def __init__(self, maxlen: int = 100_000):
        self._items: collections.deque[StateChange] = collections.deque(maxlen=maxlen)

    def add(self, t: StateChange) -> None:
        self._items.append(t)

    def recent(self, n: int) -> list[StateChange]:
        return list(self._items)[-n:]

    def clear(self) -> None:
        self._items.clear()

    def all(self) -> list[StateChange]:
        return list(self._items)

    def __len__(self) -> int:
        return len(self._items)
