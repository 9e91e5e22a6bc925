"""What a robot's injected faults did to its coordination messages, said by the robot itself
(`robotN/faults/tally`, `FaultTally`): how many it lost (`loss:P`), heard late (`latency:`),
did not hear or send while cut off (a partition) and dropped as out of range (`range:R`).

Why the robot says it rather than the analysis working it out: the recording holds what was
*sent*; what each receiver *heard* is decided in the receiver, on draws, windows and positions
only it has at that instant (failure.py: `FaultPlan.lost`, `cut_off`, `out_of_range`). Without
this a run under `loss:0.2` whose figures equal the faultless run's cannot be told from a run
where the fault never acted. The counts are cumulative; a robot says them when they changed, at
most every TALLY_PERIOD simulated seconds and once more as it stops, so a summary's figure
misses at most what a crashed robot dropped in its last TALLY_PERIOD. A robot without a
message-level fault never says it: no traffic for runs that do not need it.
"""

from __future__ import annotations

import enum

from .messages import Header, Message, message

TALLY = "faults/tally"           # robotN/faults/tally
EVERY_TALLY = f"*/{TALLY}"
TALLY_PERIOD = 0.5               # simulated s between two tallies of a robot, at most


class Cause(str, enum.Enum):
    """What an injected fault did to a coordination message: each a `FaultTally` field."""

    LOST = "lost"                  # loss:P — dropped on receipt
    DELAYED = "delayed"            # latency — heard late (not dropped)
    CUT_OFF = "cut_off"            # partition — not heard, or not sent
    OUT_OF_RANGE = "out_of_range"  # range:R — dropped on receipt


CAUSES = tuple(c.value for c in Cause)  # the field names, in order


def tally_key(robot: str) -> str:
    return f"{robot}/{TALLY}"


@message("mrta_msgs/FaultTally")
class FaultTally(Message):
    """A robot's cumulative counts since its run began (header.stamp: when, its clock)."""

    header: Header
    lost: int = 0            # loss:P — dropped on receipt
    delayed: int = 0         # latency — heard late (not dropped)
    cut_off: int = 0         # partition — not heard, or not sent
    out_of_range: int = 0    # range:R — dropped on receipt

    def counts(self) -> dict[str, int]:
        return {cause: getattr(self, cause) for cause in CAUSES}
