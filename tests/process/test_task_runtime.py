"""Tasks at run time (issue 50), across processes: a mission other terminals reach (`mrta demo
--rendezvous`), a burst of submissions and a cancellation from other terminals (`mrta task`),
every one of them accounted for in the summary and in the recording, and the summary's own
instance run again giving the same allocation records and the same changes at the same instants.
CI runs central; the slow tier every architecture."""

import json

import pytest

from mrta_zenoh.architectures import architectures
from mrta_zenoh.recording import read_recording
from tests.harness.helpers import free_port

pytestmark = pytest.mark.multiprocess

STATES = {"served", "assigned", "cancelled", "waiting"}
# submissions in the burst: enough to be a burst (one `mrta task submit --file`, every one
# accepted and accounted for), few enough that central re-planning them stays cheap (it was 200:
# the CI tier's costliest case)
BURST = 40


def burst_file(path, n):
    """n tasks on a grid of the default delivery room (12 × 8 m, no inner wall)."""
    spots = [(x, y) for x in range(-3, 5) for y in range(-3, 4)]
    lines = ["tasks:"]
    for i in range(n):
        x, y = spots[i % len(spots)]
        lines.append(f"  s{i}: {{position: [{x}.0, {y}.5], service: 1.0, priority: {i % 3}}}")
    path.write_text("\n".join(lines) + "\n")
    return path


def demo(children, out, arch, *extra, name="demo"):
    return children.mrta("demo", "--application", "delivery", "--architecture", arch,
                         "--duration", "25", "--fail", "none", "--no-live", "--no-plots",
                         "--output", str(out), *extra, name=name)


def cases():
    for arch in architectures():
        yield pytest.param(arch, marks=() if arch == "central" else (pytest.mark.slow,), id=arch)


@pytest.mark.timeout(600)
@pytest.mark.parametrize("arch", list(cases()))
def test_a_burst_and_a_cancellation_from_other_terminals_are_accounted_for_and_replay(
        children, tmp_path, arch):
    endpoint = f"tcp/127.0.0.1:{free_port()}"
    live = tmp_path / "live"
    run = demo(children, live, arch, "--speed", "1", "--rendezvous", endpoint)
    run.wait_line(lambda line: endpoint in line, 60)  # says where the run's bus is
    children.env["MRTA_RENDEZVOUS"] = endpoint  # the other terminals: that variable alone
    submit = children.mrta("task", "submit", "--file", str(burst_file(tmp_path / "b.yaml", BURST)),
                           "--timeout", "120", name="submit")
    assert submit.wait(180) == 0, submit.stderr[-5:]
    accepted = [line for line in submit.stdout if " accepted at " in line]
    assert len(accepted) == BURST, submit.stdout[-5:]
    cancel = children.mrta("task", "cancel", "t3", "--as", "dispatcher2", name="cancel")
    assert cancel.wait(120) == 0 and " accepted at " in cancel.stdout[-1], cancel.stderr[-5:]
    bad = children.mrta("task", "submit", "x1", "--set", "positon=[1,2]", name="bad")
    assert bad.wait(120) == 2 and "did you mean 'position'" in bad.stderr[-1], bad.stderr
    listing = children.mrta("task", "list", "--json", name="list")
    assert listing.wait(120) == 0
    assert len(json.loads(listing.stdout[-1])) == BURST
    assert run.wait(400) == 0, run.stderr[-20:] + run.stdout[-20:]

    summary = json.loads((live / "summary.json").read_text())
    assert summary["run_status"] == "complete" and summary["lockstep_exact"]
    runtime = summary["tasks_at_run_time"]
    rows = {r["id"]: r for r in runtime["tasks"]}
    assert len(rows) == BURST + 1 and {r["state"] for r in rows.values()} <= STATES
    assert sum(runtime["counts"].values()) == BURST + 1
    assert rows["t3"]["cancelled_at"] is not None and rows["s0"]["entered_at"] is not None
    assert runtime["served_after_cancel"] == []  # withdrawn from whoever held it
    # the malformed one is refused, counted and listed, never entered
    assert "x1" not in rows and any(r["receiver"] == "tasks" and r["reason"] == "malformed"
                                    for r in summary["refused"])
    assert summary["metrics"]["submitted"] == BURST + 1
    changes = summary["instance"]["submitted"]
    assert len(changes) == BURST + 1 and changes[-1]["op"] == "cancel"
    recorded = [r for r in read_recording(live / "run.mcap") if r[0] == "tasks/change"]
    assert len(recorded) == BURST + 1  # the recording holds what entered too

    again = tmp_path / "again"  # the summary's own instance, run again (no rendezvous)
    rerun = demo(children, again, arch, "--speed", "0", "--instance", str(live / "summary.json"),
                 name="again")
    assert rerun.wait(400) == 0, rerun.stderr[-20:] + rerun.stdout[-20:]
    replay = json.loads((again / "summary.json").read_text())
    assert replay["instance"]["submitted"] == changes
    assert replay["lockstep_exact"], (replay["run_status"], replay.get("lockstep"))
    assert replay["allocation"] == summary["allocation"]
    assert replay["tasks_at_run_time"]["tasks"] == runtime["tasks"]
