"""Behaviour unchanged: the README's delivery demo, under every registered architecture, gives
the summary that the code gave before the house was reshaped (issue 46, commit ff0d427:
tests/data/golden/).

In lockstep a run is a function of its seed, so every field the old summary.json had must come
out the same (a field the code has since added is new behaviour, not changed behaviour) except
what measures the machine, not the run:
- `wall_seconds`, `output` (the folder), and every `*_ms` (decision computation times);
- `recorded_until`: the recorder stops a wall-clock moment after the run ends, so how much of
  the robots' talk past the end it keeps is a race;
- for the same reason a time past the run's end (`ended_at`) read from that talk — a robot's
  last `to` in `who_did_what`, an allocation record's `ended_at` (MURDOCH releases its last task
  a few seconds after delivering it) — is compared as the run's end: what happens after the run
  is not the run's behaviour;
- `messages.total` within one sample per robot (and `total_per_second`, its quotient, not at
  all): a robot's velocity command carries no stamp, so it is counted by its agent's next
  stamped sample, and the last one before the end is counted only if that next sample, sent
  after the end, was recorded before the recorder stopped (the analysis's `message_rates`;
  SSI's stall run counted 6,860 and 6,855 samples on ff0d427, each robot's last command).
Run twice on ff0d427 on a loaded machine, nothing else differed.

A change that is meant to change behaviour regenerates the files, and says why in its commit:
`MRTA_WRITE_GOLDEN=1 pytest -m multiprocess tests/process/test_golden_summaries.py -k …` writes
them instead of comparing.
"""

from __future__ import annotations

import json
import os
from pathlib import Path

import pytest

from mrta_zenoh.architectures import architectures

pytestmark = pytest.mark.multiprocess

GOLDEN = Path(__file__).resolve().parent.parent / "data" / "golden"
SEED = "0"
# the README's delivery commands: each architecture as it comes, and its stall example
SCENARIOS = {"demo": (), "stall": ("--fail", "stall:robot1@5", "--duration", "80")}
# the CI tier's share (one plain run, one with a fault); the others are `slow`
CI = {("alliance", "demo"), ("central", "stall")}
MACHINE = ("wall_seconds", "output", "recorded_until")


def normalized(summary: dict) -> dict:
    """`summary` without what measures the machine, times past the run's end read as its end."""
    end = summary["ended_at"] if summary.get("ended_at") is not None else summary["duration"]

    def strip(value):
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


def differences(expected, got, path: str = "") -> list[str]:
    """Every path at which `got` departs from `expected`, for a failure people can read."""
    if isinstance(expected, dict) and isinstance(got, dict):
        out = []
        for k in sorted(expected, key=str):
            if k not in expected:
                continue  # added since: new behaviour, not changed
            if k not in got:
                out.append(f"{path}/{k}: missing")
            else:
                out += differences(expected[k], got[k], f"{path}/{k}")
        return out
    if isinstance(expected, list) and isinstance(got, list) and len(expected) == len(got):
        return [d for i, (e, g) in enumerate(zip(expected, got))
                for d in differences(e, g, f"{path}[{i}]")]
    return [] if expected == got else [f"{path}: {expected!r} became {got!r}"]


def cases():
    for arch in architectures():
        for scenario in SCENARIOS:
            marks = () if (arch, scenario) in CI else (pytest.mark.slow,)
            yield pytest.param(arch, scenario, marks=marks, id=f"{arch}-{scenario}")


@pytest.mark.timeout(420)
@pytest.mark.parametrize("arch,scenario", list(cases()))
def test_the_readme_delivery_demo_gives_the_summary_it_gave_before(children, tmp_path, arch,
                                                                  scenario):
    golden = GOLDEN / f"delivery_{arch}_{scenario}.json"
    out = tmp_path / "run"
    demo = children.mrta("-q", "demo", "--application", "delivery", "--architecture", arch,
                         "--speed", "0", "--no-live", "--no-plots", "--seed", SEED,
                         "--output", str(out), *SCENARIOS[scenario], name="demo")
    assert demo.wait(360) == 0, demo.tail(30)
    got = normalized(json.loads((out / "summary.json").read_text()))
    if os.environ.get("MRTA_WRITE_GOLDEN") == "1":
        golden.write_text(json.dumps(got, indent=1, sort_keys=True) + "\n")
        pytest.skip(f"wrote {golden.name}")
    assert golden.exists(), (f"no golden summary for {arch} ({golden.name}): a new architecture "
                             "writes its own with MRTA_WRITE_GOLDEN=1 once its demo is right")
    expected = json.loads(golden.read_text())
    # else the run is not a function of its seed: say what lockstep gave up, and what differs
    assert got["lockstep"] and got["lockstep_exact"], (
        {k: got.get(k) for k in ("lockstep_given_up", "lockstep_forgiven", "run_status",
                                 "disturbances")}, differences(expected, got)[:20])
    total, expected_total = got["messages"].pop("total"), expected["messages"].pop("total")
    assert abs(total - expected_total) <= len(expected["robots"]), (total, expected_total)
    assert not differences(expected, got), "\n".join(differences(expected, got)[:40])
