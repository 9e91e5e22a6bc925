"""Behaviour unchanged: the README's delivery demo, under every registered architecture, gives
the summary that the code gave before the house was reshaped (issue 46, commit ff0d427:
tests/data/golden/).

In lockstep a run is a function of its seed, so every field the old summary.json had must come
out the same (a field the code has since added is new behaviour, not changed behaviour) except
what measures the machine, not the run (supervisor/mission/compare.py says which; SSI's stall
run counted 6,860 and 6,855 samples on ff0d427, each robot's last command). Run twice on
ff0d427 on a loaded machine, nothing else differed.

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
from mrta_supervisor.mission.compare import differences, normalized, run_differences

pytestmark = pytest.mark.multiprocess

GOLDEN = Path(__file__).resolve().parent.parent / "data" / "golden"
SEED = "0"
# the README's delivery commands: each architecture as it comes, and its stall example
SCENARIOS = {"demo": (), "stall": ("--fail", "stall:robot1@5", "--duration", "80")}
# the CI tier's share (one plain run, one with a fault); the others are `slow`
CI = {("alliance", "demo"), ("central", "stall")}


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
    # not -q: a plain demo must also print no WARNING and no alarm — delivered tasks are
    # `done`, not unattended, and the end of the run is no stopped clock (every delivery is
    # done by ≈ 26 s: unattended for 30 s from then was alarmed at 45–58 s of the 60 s run,
    # and `clock_stopped` once the simulator stopped at 60 s)
    demo = children.demo(out, "--application", "delivery", "--architecture", arch, "--no-plots",
                         "--seed", SEED, *SCENARIOS[scenario])
    summary = demo.summary(360)
    if scenario == "demo":
        printed = demo.stdout + demo.stderr
        assert not [line for line in printed if "WARNING" in line or "alarm" in line], printed
    got = normalized(summary)
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
    # the golden file is normalized already (normalizing again changes nothing)
    assert not run_differences(expected, got), "\n".join(run_differences(expected, got)[:40])
