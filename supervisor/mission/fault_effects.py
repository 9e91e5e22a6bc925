"""What the run's injected faults did to the robots' coordination messages, summed over the
robots from each one's last tally in the recording (mrta_zenoh.fault_tally: why the robots say
it themselves). A summary's `fault_effects`; results.csv's `faults.<cause>` columns. And, the
same way, what each process refused of what it heard (mrta_zenoh.refusal_tally): a summary's
`refused`."""

from __future__ import annotations

import math
from collections.abc import Iterable

from mrta_zenoh.codec import DecodeError, decode, type_from_encoding
from mrta_zenoh.fault_tally import CAUSES, TALLY, FaultTally
from mrta_zenoh.keys import first_chunk
from mrta_zenoh.messages import Message
from mrta_zenoh.refusal_tally import REFUSED, RefusedTally

from .summary import Refusal


def latest_tallies(records: Iterable, names: Iterable[str], suffix: str, kind: type[Message],
                   until: float = math.inf) -> dict[str, Message]:
    """Each named process's latest message of type `kind` on `<name>/<suffix>`, stamped at or
    before `until`, from a sender its key and header agree on (a malformed one is dropped like
    any malformed message)."""
    team = set(names)
    last: dict[str, tuple[float, Message]] = {}
    depth = suffix.count("/") + 1
    for key, enc, t, payload in records:
        if not key.endswith("/" + suffix) or key.count("/") != depth:
            continue
        name = first_chunk(key)
        if name not in team:
            continue
        try:
            msg = decode(type_from_encoding(enc), payload)
        except DecodeError:
            continue
        stamp = msg.header.stamp if isinstance(msg, kind) else None
        if stamp is None or msg.header.frame_id.strip("/") != name or stamp > until + 1e-6:
            continue
        if name not in last or stamp >= last[name][0]:
            last[name] = (stamp, msg)
    return {name: msg for name, (_, msg) in last.items()}


def fault_effects(records: Iterable, robots: Iterable[str], until: float) -> dict[str, int]:
    """Each cause's count over the team, from each robot's latest tally stamped at or before
    `until` (simulated s): {} when no robot said one — no message-level fault acted, or the
    run had none."""
    last = latest_tallies(records, robots, TALLY, FaultTally, until)
    if not last:
        return {}
    return {cause: sum(getattr(m, cause) for m in last.values()) for cause in CAUSES}


def refused_traffic(records: Iterable, processes: Iterable[str]) -> list[Refusal]:
    """What each process of the run refused, from its latest tally (the one it said as it
    stopped included: a forgery in the last instants counts too), forged entries first."""
    out = [Refusal(name, sender, kind, reason, n, forged)
           for name, msg in sorted(latest_tallies(records, processes, REFUSED,
                                                  RefusedTally).items())
           for (kind, sender, reason, forged), n in msg.entries().items()]
    return sorted(out, key=lambda r: (not r.forged, r.receiver, r.sender, r.kind, r.reason))
