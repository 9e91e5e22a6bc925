"""What a process refused of what it heard, said by the process itself (`<name>/refused/tally`,
`RefusedTally`): per message kind, sender and reason, how many samples (or claims within them)
it did not believe — the driver's checks (a key and header naming two senders, a sender off the
roster) and its decision logic's (`Coordinator.refuse`: a claim its sender cannot make, a
message no process of the run would send). Like the fault tally (fault_tally.py) the receiver says it, because only the
receiver knows what it refused; the summary sums the last tally of each process.

Each entry says whether it is *forged*: evidence that someone said what no process of the run
would (a header that disagrees with its key, a served task its sender never held, a round far
ahead). A run that refused forged traffic is not the run its seed describes (`run_status`
disturbed, the cause named). Other refusals are counted and shown but judge nothing: a message
from a robot off the roster (a stranger on a shared bus) — but for one: a task reported served
by a second robot (SERVED_TWICE, central's dispatcher) is no forgery, and yet a task was served
twice (a cut let both robots act): the run is disturbed, and says so. A message from a teammate whose token has not come
yet is not in the tally (a start-up race whose count depends on the machine): the driver
counts and logs it.

Bounded whatever a flood sends: senders from the network are escaped and cut, and beyond
MAX_ENTRIES distinct entries the rest are counted under the sender OTHERS.
"""

from __future__ import annotations

import collections
from typing import Iterable, Mapping

from .messages import Header, Message, message
from .untrusted import visible

REFUSED = "refused/tally"       # <name>/refused/tally
EVERY_REFUSED = f"*/{REFUSED}"
MAX_ENTRIES = 64                # distinct (kind, sender, reason, forged) entries a tally holds
OTHERS = "(others)"             # the sender every entry beyond MAX_ENTRIES is counted under
MAX_NAME = 40                   # characters of a sender's name from the network kept

# the driver's reasons (robot_agent/runtime/loop.py)
MISMATCH = "key_header_mismatch"  # its key names one sender, its header another: forged
OFF_ROSTER = "off_roster"         # its sender is not on the team (--team): a stranger
MALFORMED = "malformed"           # an index or a name outside the instance: refused whole
MISADDRESSED = "misaddressed"     # from a sender, or to a receiver, it cannot come from or go to
OTHER_INSTANCE = "other_instance"  # counts robots and tasks in another instance (its digest)
# a decision logic's reason the summary reads (module docstring): a task reported served after
# another robot served it — served twice (central's dispatcher says it)
SERVED_TWICE = "served_twice"

Entry = tuple[str, str, str, bool]  # (kind, sender, reason, forged)


def refused_key(name: str) -> str:
    return f"{name}/{REFUSED}"


class Refusals:
    """A bounded count of entries (module docstring). Not thread-safe: its owner locks."""

    def __init__(self) -> None:
        self.counts: collections.Counter[Entry] = collections.Counter()

    def add(self, kind: str, sender: str, reason: str, forged: bool, n: int = 1) -> None:
        entry = (kind, visible(sender, MAX_NAME), reason, forged)
        if entry not in self.counts and len(self.counts) >= MAX_ENTRIES:
            entry = (kind, OTHERS, reason, forged)
        self.counts[entry] += n

    def merged(self, more: Mapping[Entry, int]) -> dict[Entry, int]:
        out = Refusals()
        for entries in (self.counts, more):
            for (kind, sender, reason, forged), n in entries.items():
                out.add(kind, sender, reason, forged, n)
        return dict(out.counts)


@message("mrta_msgs/RefusedTally")
class RefusedTally(Message):
    """A process's cumulative counts since its run began, one entry per index of the parallel
    fields (header.stamp: when, its clock); `forged[i]` 1 or 0."""

    header: Header
    kinds: tuple[str, ...] = ()
    senders: tuple[str, ...] = ()
    reasons: tuple[str, ...] = ()
    forged: tuple[int, ...] = ()
    counts: tuple[int, ...] = ()

    def entries(self) -> dict[Entry, int]:
        """Entry → count; {} when the fields disagree in length (a malformed tally)."""
        fields = (self.kinds, self.senders, self.reasons, self.forged, self.counts)
        if len({len(f) for f in fields}) != 1:
            return {}
        return {(k, s, r, bool(f)): n for k, s, r, f, n in zip(*fields) if n > 0}


def tally(header: Header, counts: Mapping[Entry, int]) -> RefusedTally:
    entries: Iterable[tuple[Entry, int]] = sorted(counts.items())
    rows = [(k, s, r, int(f), n) for (k, s, r, f), n in entries]
    return RefusedTally(header, *(tuple(col) for col in zip(*rows))) if rows \
        else RefusedTally(header)
