"""cbba_msgs: CBBA's consensus message (Choi et al. 2009, §IV-B) on the bus.

One message carries everything a robot tells its neighbours: for each task it knows a winner
of, the winning robot and bid (the paper's z and y), its time stamps of the latest information
from each robot (s), and the tasks served. Tasks and robots are named by their index in the
instance every robot reads (tasks and robots in file order): a winner entry is three small
numbers, and a task nobody has won is left out (the paper's "none"), so a message grows with the
tasks won, not with the instance. It carries that instance's digest (IndexedMessage: a robot on
another instance is refused, not misread).
"""

from __future__ import annotations

from mrta_zenoh.messages import Finite, Header, IndexedMessage, message


@message("cbba_msgs/Bids")
class Bids(IndexedMessage):
    """`winners`: (task, robot, winning bid) for each task the sender knows a winner of;
    `stamps`: (robot, time) — when the sender last had information from each robot it heard
    from, itself included (its send time); `done`: tasks served, by anyone, as far as it knows;
    `x`, `y`: where it is (a range-limited network drops messages from too far); `ms`: what its
    last decision cost (below)."""

    header: Header
    winners: tuple[tuple[int, int, Finite], ...]
    stamps: tuple[tuple[int, Finite], ...]
    done: tuple[int, ...]
    x: Finite
    y: Finite
    # wall ms this robot spent on its bundle (release, re-check, build) since its last Bids,
    # when its table changed (its decision); 0 on a resend of an unchanged table
    ms: Finite = 0.0
    # the teammates it counts out while their token lives, and why (`robot3:stalled`): what the
    # summary's declared stalls are read from (own_route.RouteLogic.declared)
    out: tuple[str, ...] = ()


MESSAGES = {"bids": Bids}
