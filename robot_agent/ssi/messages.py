"""ssi_msgs: SSI's rounds on the bus (docs/ssi.md).

The auctioneer (the lowest-id live robot) publishes a `Round`: its number and the state of every
task, which is all a bidder needs; each robot answers with a `Bid` addressed to it (its key's
sub-key) for that round. Tasks and robots are named by their index in the instance every robot
reads (tasks and robots in file order), so a round is one small number per task; each message
carries that instance's digest (IndexedMessage: a robot on another instance is refused, not
misread).
"""

from __future__ import annotations

import struct
import zlib

from mrta_zenoh.messages import Finite, Header, IndexedMessage, message

OPEN, UNKNOWN, DONE = -1, -2, -3  # a task's state in Round.owners besides its owner's index


@message("ssi_msgs/Round")
class Round(IndexedMessage):
    """`owners[j]`: the index of the robot task j was awarded to, or OPEN (to bid on), UNKNOWN
    (not arrived yet) or DONE (served); `award`: the task this round's opening awarded (its
    winner is its owner; −1: none), `cost` its winning bid and `ms` the computation time of
    that award (the slowest bid of the round and the winner determination, auction.Ssi);
    `out`: the robots the auctioneer leaves out while their token lives, and why
    (`robot3:stalled`, `robot3:silent`) — what the summary's declared stalls are read from."""

    header: Header
    round: int
    owners: tuple[int, ...]
    award: int
    cost: Finite
    ms: Finite = 0.0
    out: tuple[str, ...] = ()


@message("ssi_msgs/Bid")
class Bid(IndexedMessage):
    """A robot's bid in `round` of `auctioneer`'s: what adding `task` to its path costs (task −1:
    nothing it can serve is open), and the tasks it served that the last Round it heard did not
    yet show DONE (so a task served just before its server died is not auctioned again);
    `ms`: how long computing the bid took (wall time, a measurement); `seen`: the digest of
    the Round it answers (`digest`: its owners, as sent), so the auctioneer knows the Round its
    bidder follows is one it sent (auction.Ssi: a forged Round under its key is not)."""

    header: Header
    auctioneer: str
    round: int
    task: int
    cost: Finite
    served: tuple[int, ...]
    ms: Finite = 0.0
    seen: int | None = None


def digest(owners: tuple[int, ...] | list[int]) -> int:
    """A Round's owners in one number (CRC-32 of their little-endian 32-bit values)."""
    return zlib.crc32(struct.pack(f"<{len(owners)}i", *owners))


MESSAGES = {"round": Round, "bid": Bid}
