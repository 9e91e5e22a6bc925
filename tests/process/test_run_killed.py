"""A run whose dispatcher or recorder is SIGKILLed from outside still ends in a summary (issue
51.5): what can be known from the recording, marked so — disturbed (the dispatcher), incomplete
(the recorder) — never complete and exact, and `mrta demo` exits 1 after printing it. Before,
the runner raised on the dead child and no summary was written, though the recording was whole.
Both `slow`: the logic is tested in process (tests/test_summary_faults.py)."""

from __future__ import annotations

import time

import pytest

from tests.harness.helpers import kill_descendant

pytestmark = [pytest.mark.multiprocess, pytest.mark.slow]


def killed_run(children, out, *needles: str, after: str = "t=") -> tuple[dict, str]:
    """A central demo at speed 1 (≥ 30 wall seconds once the simulator runs); once it is under
    way (a progress line starting with `after`: `t= 1.0s …`), the first process under it whose
    command line holds `needles` is SIGKILLed. (Killed before every process is up, a process is a start-up
    failure: no run, no summary.)"""
    demo = children.demo(out, "--application", "delivery", "--architecture", "central",
                         "--duration", "30", "--speed", "1", "--fail", "none", "--no-plots")
    deadline = time.monotonic() + 180
    while not any(line.startswith(after) for line in demo.stdout):
        assert time.monotonic() < deadline and demo.proc.poll() is None, demo.tail(30)
        time.sleep(0.2)
    assert kill_descendant(demo.proc.pid, *needles) is not None
    return demo.summary(240, code=1), "\n".join(demo.stdout + demo.stderr)


@pytest.mark.timeout(300)
def test_a_sigkilled_dispatcher_leaves_a_disturbed_summary(children, tmp_path):
    s, printed = killed_run(children, tmp_path / "out", "dispatcher", "--params")
    assert s["run_status"] == "disturbed" and s["lockstep_exact"] is False
    (d,) = [d for d in s["disturbances"] if d["process"] == "dispatcher"]
    assert d["ended"] == "killed by SIGKILL", s["disturbances"]
    assert "dispatcher killed by SIGKILL" in printed


@pytest.mark.timeout(300)
@pytest.mark.parametrize("after", ["t=", "t= 1"])  # at once (nothing recorded yet); after 10 s
def test_a_sigkilled_recorder_leaves_an_incomplete_summary(children, tmp_path, after):
    s, printed = killed_run(children, tmp_path / "out", "view", "--output", after=after)
    assert s["run_status"] == "incomplete" and s["lockstep_exact"] is False
    assert s["recorded_until"] is None or s["recorded_until"] < 30.0 - 1.0
    (d,) = [d for d in s["disturbances"] if d["process"] == "recorder"]
    assert d["ended"] == "killed by SIGKILL", s["disturbances"]
    assert "the recording does not cover the whole mission" in printed
