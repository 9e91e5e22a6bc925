"""What the run's injected faults did to the robots' coordination messages, summed over the
robots from each one's last tally in the recording (mrta_zenoh.fault_tally: why the robots say
it themselves). A summary's `fault_effects`; results.csv's `faults.<cause>` columns."""

from __future__ import annotations

from collections.abc import Iterable

from mrta_zenoh.codec import DecodeError, decode, type_from_encoding
from mrta_zenoh.fault_tally import CAUSES, TALLY, FaultTally
from mrta_zenoh.keys import first_chunk


def fault_effects(records: Iterable, robots: Iterable[str], until: float) -> dict[str, int]:
    """Each cause's count over the team, from each robot's latest tally stamped at or before
    `until` (simulated s): {} when no robot said one — no message-level fault acted, or the
    run had none."""
    team = set(robots)
    last: dict[str, tuple[float, FaultTally]] = {}
    for key, enc, t, payload in records:
        if not key.endswith("/" + TALLY) or key.count("/") != 2:
            continue
        robot = first_chunk(key)
        if robot not in team:
            continue
        try:
            msg = decode(type_from_encoding(enc), payload)
        except DecodeError:
            continue  # a malformed tally is dropped like any malformed message
        stamp = msg.header.stamp if isinstance(msg, FaultTally) else None
        if stamp is None or msg.header.frame_id.strip("/") != robot or stamp > until + 1e-6:
            continue
        if robot not in last or stamp >= last[robot][0]:
            last[robot] = (stamp, msg)
    if not last:
        return {}
    return {cause: sum(getattr(m, cause) for _, m in last.values()) for cause in CAUSES}
