"""The run's key table and a step's claims by index in it (docs/wire-format.md: a Step names
its claims by index, and carries only the keys new since the previous one)."""

from __future__ import annotations

import sys
from array import array

# hashlib's own BLAKE2b, without hashlib: importing hashlib loads OpenSSL (_hashlib) into every
# agent (tests/test_agent_imports.py)
from _blake2 import blake2b

from .protocol import Step


class KeyTable:
    """The keys a run's claims count, in the order the simulator first claimed them.

    A Step carries its claims as counts by index in this table, and only the keys new since the
    previous step (with 100 robots a Step would name about 1,100 keys, and each of 100
    participants decode every name at every step). The table only grows within a run (the
    simulator starts a new one, sent whole, when it passes MAX_KEYS); `digest` (BLAKE2b of the
    keys, each ended by a newline — a CRC would be forged by anybody) lets a participant check
    that its copy is the simulator's: one that missed a step, or took a forged one, passes steps
    over until a whole table comes — the simulator sends one to a newcomer, and to a
    participant silent for REPORT_AFTER or given up."""

    def __init__(self) -> None:
        self.keys: list[str] = []
        self.index: dict[str, int] = {}
        self._hash = blake2b(digest_size=16)
        self.digest = self._hash.digest()
        self.generation = 0  # changes when keys are replaced, not only appended (Books)

    def __len__(self) -> int:
        return len(self.keys)

    def add(self, keys) -> None:
        """The simulator's side: append those of `keys` the table does not have (sorted)."""
        self._append(sorted(keys - self.index.keys()))

    def _append(self, new: list[str], hashed=None) -> None:
        """Append `new`; `hashed`: the digest's state with them already in (take checked it)."""
        if hashed is None:
            if not new:
                return
            hashed = self._hash.copy()
            hashed.update(_joined(new))
        n = len(self.keys)
        self.keys.extend(new)
        self.index.update(zip(new, range(n, n + len(new))))
        self._hash, self.digest = hashed, hashed.digest()

    def take(self, step: "Step") -> str | None:
        """A participant's side: make this table the one `step` counts by. None: done; "":
        it cannot be known from this step (one carrying keys was missed, or this copy is not
        the simulator's) — a whole table will come; otherwise why the step is malformed."""
        base, keys, n = step.base, step.keys, len(self.keys)
        if len(step.counts) % WORD:
            return f"its counts are {len(step.counts)} bytes, not whole {WORD}-byte words"
        if base < 0 or count_of(step) != base + len(keys):
            return f"it has {count_of(step)} counts for {base} + {len(keys)} keys"
        if base > n:
            return ""
        if base < n:  # a whole table (a newcomer's) or part of one: compared with this copy
            keys = self.keys[:base] + keys
            if keys[:n] != self.keys:  # not the same table: this copy was not the simulator's
                return self._replace(keys, step.table_digest)
            keys = keys[n:]
        if not keys:
            return None if self.digest == step.table_digest else ""
        if len(set(keys)) != len(keys) or not self.index.keys().isdisjoint(keys):
            return "its keys repeat"
        hashed = self._hash.copy()
        hashed.update(_joined(keys))
        if hashed.digest() != step.table_digest:
            return ""
        self._append(keys, hashed)
        return None

    def _replace(self, keys: list[str], digest: bytes) -> str | None:
        if len(set(keys)) != len(keys):
            return "its keys repeat"
        hashed = blake2b(_joined(keys), digest_size=16)
        if hashed.digest() != digest:
            return ""
        self.keys, self.index = [], {}
        self._append(keys, hashed)
        self.generation += 1
        return None


def _joined(keys: list[str]) -> bytes:
    return "".join(k + "\n" for k in keys).encode()


WORD = 8  # bytes per count in a Step (unsigned 64-bit)


def count_of(step: Step) -> int:
    """How many counts a Step carries (KeyTable.take refuses one that is not whole words)."""
    return len(step.counts) // WORD


class Claims:
    """What a step requires, by key: `counts[i]` samples on the table's i-th key, as unsigned
    64-bit words (`array('Q')`, this machine's byte order). A step's counts cover its table:
    the table changes only when a step is taken (which then is the one pending) or when its run
    ends (emptied)."""

    __slots__ = ("table", "counts")

    def __init__(self, table: KeyTable, counts) -> None:
        self.table = table
        self.counts = counts if isinstance(counts, array) else array("Q", counts)

    @classmethod
    def of(cls, table: KeyTable, step: Step) -> "Claims":
        """A Step's claims (its counts are whole words: KeyTable.take checked them)."""
        counts = array("Q")
        counts.frombytes(step.counts)
        if sys.byteorder == "big":
            counts.byteswap()
        return cls(table, counts)

    def packed(self) -> bytes:
        """The counts as a Step carries them (little-endian words)."""
        if sys.byteorder == "big":
            swapped = array("Q", self.counts)
            swapped.byteswap()
            return swapped.tobytes()
        return self.counts.tobytes()

    def get(self, key: str) -> int | None:
        i = self.table.index.get(key)
        return None if i is None else self.counts[i]

