"""A normal `mrta demo` prints no WARNING: delivered tasks are `done`, not
unattended, and the end of the run is no stopped clock. `slow`: the CI tier checks the same
on its golden delivery demo (tests/process/test_golden_summaries.py, alliance-demo), without
the pictures this run also draws."""


import pytest

pytestmark = [pytest.mark.multiprocess, pytest.mark.slow]


def test_a_delivery_demo_ends_without_a_warning(children, tmp_path):
    """Every delivery is done by ≈ 26 s: unattended for 30 s from then was alarmed at 45–58 s
    of the 60 s run, and `clock_stopped` once the simulator stopped at 60 s."""
    out = tmp_path / "demo"
    demo = children.demo(out, "--application", "delivery")
    summary = demo.summary(240)
    assert summary["metrics"]["completed"] == 4 and summary["duration"] == 60
    printed = demo.stdout + demo.stderr
    assert not [line for line in printed if "WARNING" in line or "alarm" in line], printed
