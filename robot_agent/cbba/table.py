"""CBBA's conflict resolution: Table 1 of Choi, Brunet & How (IEEE T-RO 25(4), 2009, p. 917) —
what receiver i does with task j when sender k tells it who won j.

Each side's view of task j is (winner, winning bid); `NONE` is no winner (bid 0). Time stamps
`s_k[m]` / `s_i[m]` are when sender and receiver last had information from robot m (directly or
relayed); a robot never heard from has no stamp (−inf). The three actions:

* **update**: y_ij = y_kj, z_ij = z_kj (take the sender's view);
* **reset**:  y_ij = 0,    z_ij = none;
* **leave**:  keep the receiver's view.

The 17 rows, in the paper's order (m, n: robots other than i and k, m ≠ n):

| row | sender's z_kj | receiver's z_ij | receiver's action |
| --- | --- | --- | --- |
| 1 | k | i | update if y_kj > y_ij |
| 2 | k | k | update |
| 3 | k | m | update if s_km > s_im or y_kj > y_ij |
| 4 | k | none | update |
| 5 | i | i | leave |
| 6 | i | k | reset |
| 7 | i | m | reset if s_km > s_im |
| 8 | i | none | leave |
| 9 | m | i | update if s_km > s_im and y_kj > y_ij |
| 10 | m | k | update if s_km > s_im, else reset |
| 11 | m | m | update if s_km > s_im |
| 12 | m | n | below |
| 13 | m | none | update if s_km > s_im |
| 14 | none | i | leave |
| 15 | none | k | update |
| 16 | none | m | update if s_km > s_im |
| 17 | none | none | leave |

Row 12: update if s_km > s_im and s_kn > s_in; update if s_km > s_im and y_kj > y_ij; reset
if s_kn > s_in and s_im > s_km. Every condition not met means leave.

"y_kj > y_ij" is a bid comparison with our tie rule: an equal bid is higher when its winner has
the lower id (the paper leaves ties to the implementation; MIT's reference code breaks them by
agent index, as we do by id).
"""

from __future__ import annotations

from typing import Mapping, NamedTuple, Sequence

NONE = -1  # no winner
UPDATE, RESET, LEAVE = "update", "reset", "leave"


class View(NamedTuple):
    """One robot's view of a task: its winner (a robot index or NONE) and the winning bid."""

    winner: int
    bid: float


class Decision(NamedTuple):
    action: str
    row: int


def higher(a: View, b: View, rank: Sequence[int]) -> bool:
    """Whether bid `a` beats bid `b`: larger, or equal and its winner has the lower id."""
    return a.bid > b.bid or (a.bid == b.bid and a.winner != NONE
                             and (b.winner == NONE or rank[a.winner] < rank[b.winner]))


def resolve(i: int, k: int, sender: View, receiver: View, s_k: Mapping[int, float],
            s_i: Mapping[int, float], rank: Sequence[int]) -> Decision:
    """Table 1: receiver i's action on one task, given sender k's view and its own, the
    sender's time stamps `s_k` and its own `s_i` (robot → time; a missing robot: never heard),
    both as they stood before this message. `rank`: each robot's place in id order (ties)."""
    zk, zi = sender.winner, receiver.winner
    inf = float("-inf")

    def newer(m: int) -> bool:  # s_km > s_im: the sender has later information from m
        return s_k.get(m, inf) > s_i.get(m, inf)

    def beats() -> bool:  # y_kj > y_ij
        return higher(sender, receiver, rank)

    if zk == k:
        if zi == i:
            return Decision(UPDATE if beats() else LEAVE, 1)
        if zi == k:
            return Decision(UPDATE, 2)
        if zi == NONE:
            return Decision(UPDATE, 4)
        return Decision(UPDATE if newer(zi) or beats() else LEAVE, 3)
    if zk == i:
        if zi == i:
            return Decision(LEAVE, 5)
        if zi == k:
            return Decision(RESET, 6)
        if zi == NONE:
            return Decision(LEAVE, 8)
        return Decision(RESET if newer(zi) else LEAVE, 7)
    if zk != NONE:
        m = zk
        if zi == i:
            return Decision(UPDATE if newer(m) and beats() else LEAVE, 9)
        if zi == k:
            return Decision(UPDATE if newer(m) else RESET, 10)
        if zi == m:
            return Decision(UPDATE if newer(m) else LEAVE, 11)
        if zi == NONE:
            return Decision(UPDATE if newer(m) else LEAVE, 13)
        n = zi
        if newer(m) and (newer(n) or beats()):
            return Decision(UPDATE, 12)
        if newer(n) and s_i.get(m, inf) > s_k.get(m, inf):
            return Decision(RESET, 12)
        return Decision(LEAVE, 12)
    if zi == i:
        return Decision(LEAVE, 14)
    if zi == k:
        return Decision(UPDATE, 15)
    if zi == NONE:
        return Decision(LEAVE, 17)
    return Decision(UPDATE if newer(zi) else LEAVE, 16)
