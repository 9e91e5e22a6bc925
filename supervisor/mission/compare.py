"""Two summaries of one seed compared: what the golden summaries (tests/process/
test_golden_summaries.py), the agent hosts' identity (tests/process/test_hosts_identity.py) and
benchmarks/hosts.py all ask — the same run, field for field, but for what measures the machine.

In lockstep a run is a function of its seed, so every field must come out the same except:
- `wall_seconds`, `output` (the folder), and every `*_ms` (decision computation times);
- `recorded_until`: the recorder stops a wall-clock moment after the run ends, so how much of
  the robots' talk past the end it keeps is a race;
- for the same reason a time past the run's end (`ended_at`) read from that talk — a robot's
  last `to` in `who_did_what`, an allocation record's `ended_at` (a robot gives its last task
  back a tick after delivering it) — is compared as the run's end;
- `messages.total` within one sample per robot (and `total_per_second`, its quotient, not at
  all): a robot's velocity command carries no stamp, so it is counted by its agent's next
  stamped sample, and the last one before the end is counted only if that next sample, sent
  after the end, was recorded before the recorder stopped (analysis.message_rates).
"""

from __future__ import annotations

from typing import Any

MACHINE = ("wall_seconds", "output", "recorded_until")


def normalized(summary: dict) -> dict:
    """`summary` without what measures the machine, times past the run's end read as its end."""
    end = summary["ended_at"] if summary.get("ended_at") is not None else summary["duration"]

    def strip(value: Any) -> Any:
        if isinstance(value, dict):
            return {k: strip(v) for k, v in value.items() if not k.endswith("_ms")}
        if isinstance(value, list):
            return [strip(v) for v in value]
        return value

    s = strip({k: v for k, v in summary.items() if k not in MACHINE})
    s.get("messages", {}).pop("total_per_second", None)
    for spans in s.get("who_did_what", {}).values():
        for span in spans:
            span["to"] = min(span["to"], end)
    for record in s.get("allocation") or []:
        if record.get("ended_at") is not None:
            record["ended_at"] = min(record["ended_at"], end)
    return s


def differences(expected: Any, got: Any, path: str = "") -> list[str]:
    """Every path at which `got` departs from `expected`, for a failure people can read; a
    field only `got` has is new behaviour, not changed behaviour, and is not listed."""
    if isinstance(expected, dict) and isinstance(got, dict):
        out = []
        for k in sorted(expected, key=str):
            if k not in got:
                out.append(f"{path}/{k}: missing")
            else:
                out += differences(expected[k], got[k], f"{path}/{k}")
        return out
    if isinstance(expected, list) and isinstance(got, list) and len(expected) == len(got):
        return [d for i, (e, g) in enumerate(zip(expected, got))
                for d in differences(e, g, f"{path}[{i}]")]
    return [] if expected == got else [f"{path}: {expected!r} became {got!r}"]


def run_differences(expected: dict, got: dict) -> list[str]:
    """How two summaries of one seed differ but for the machine's fields (module docstring):
    both normalized, the bus's whole count within one sample per robot."""
    a, b = normalized(expected), normalized(got)
    total, got_total = a.get("messages", {}).pop("total", 0), b.get("messages", {}).pop("total", 0)
    out = differences(a, b)
    if abs(total - got_total) > len(expected.get("robots", ())):
        out.append(f"/messages/total: {total!r} became {got_total!r}")
    return out
