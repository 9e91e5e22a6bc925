"""What hearing a `Bids` reads off it before any rule applies — the indices it names, its
lowest and highest winning bid, its winners and time stamps as maps — worked out once per
message object (`read`), not once per robot hearing it.

Why: CBBA is N² traffic — every robot hears every teammate's table, at least once a
`resend_period` — and in an agent host one decoded message reaches every robot of the host
(mrta_zenoh.bus.zenoh_bus, `_hand_over`; the synchronous rounds hand one object to every
neighbour too). At 100 robots reading each message afresh per robot was most of what hearing
cost (issue 47: `Cbba._named` alone was half of the host's hearing in a profile). What is read
here depends on the message alone, and messages are frozen, so every robot reads the same; the
rules that depend on the robot — its instance's size, its tasks' rewards, Table 1 against its
own table — still run per robot (bundle.Cbba.hear), so what each robot does is unchanged.

Not a departure from the paper (Choi, Brunet & How 2009, §IV-B): every message is still heard
and applied whole by every robot, the periodic resends included. Cutting those resends was
weighed and left: a resend of an unchanged table still carries the sender's newer time stamps,
which Table 1 compares, so hearing it can change a receiver's table — and which messages exist
is part of a run's summary (its message counts).
"""

from __future__ import annotations

import math

from .messages import Bids

CACHED = 512  # messages remembered: more than a 100-robot team sends between two ticks


class Read:
    """`named`: (the least index named, the largest task index, the largest robot index; -1
    for none); `lowest`, `highest`: its winning bids' extremes (NaN if one is NaN, None with no
    winner); `winners`: task → (winner, bid), the last entry of a task that is named twice;
    `stamps`: robot → time stamp. Shared by every robot that hears the message: read only."""

    __slots__ = ("named", "lowest", "highest", "winners", "stamps")

    def __init__(self, msg: Bids):
        tasks, robots, bids = zip(*msg.winners) if msg.winners else ((), (), ())
        stamped = next(zip(*msg.stamps), ())
        tasks, robots = tasks + tuple(msg.done), robots + tuple(stamped)
        self.named = (min(tasks + robots, default=0), max(tasks, default=-1),
                      max(robots, default=-1))
        if not bids:
            self.lowest = self.highest = None
        elif any(b != b for b in bids):  # min and max of a NaN depend on where it stands
            self.lowest = self.highest = math.nan
        else:
            self.lowest, self.highest = min(bids), max(bids)
        self.winners = {j: (w, y) for j, w, y in msg.winners}
        self.stamps = dict(msg.stamps)


_read: dict[int, tuple[Bids, Read]] = {}  # id(message) → (the message, kept alive: ids stay
                                          # unique while cached, what was read of it)


def read(msg: Bids) -> Read:
    """What `msg` says, read once for every robot of this process that hears it."""
    hit = _read.get(id(msg))
    if hit is not None and hit[0] is msg:
        return hit[1]
    done = Read(msg)
    if len(_read) >= CACHED:
        _read.pop(next(iter(_read)), None)  # the oldest: heard by everyone by now
    _read[id(msg)] = (msg, done)
    return done
