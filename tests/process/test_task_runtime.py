"""Tasks at run time (issue 50), across processes: a mission other terminals reach (`mrta demo
--rendezvous`), a burst of submissions and a cancellation from other terminals (`mrta task`),
every one of them accounted for in the summary and in the recording, the submitted tasks served
(an urgent one early), and the summary's own instance run again giving the same allocation
records and the same changes at the same instants. CI runs central with a burst of 10; the slow
tier every architecture that takes submitted tasks with a burst of 200 (issue 50's figure), and
ALLIANCE's and MURDOCH's refusal."""

import json

import pytest

from mrta_zenoh.architectures import architectures
from mrta_zenoh.recording import read_recording
from mrta_supervisor.experiment.results import MACHINE_TIME
from tests.harness.helpers import free_port

pytestmark = pytest.mark.multiprocess

STATES = {"served", "assigned", "cancelled", "waiting"}


def burst_file(path, n):
    """n tasks on a grid of the default delivery room (12 × 8 m, no inner wall)."""
    spots = [(x, y) for x in range(-3, 5) for y in range(-3, 4)]
    lines = ["tasks:"]
    for i in range(n):
        x, y = spots[i % len(spots)]
        lines.append(f"  s{i}: {{position: [{x}.0, {y}.5], service: 1.0, priority: {i % 3}}}")
    path.write_text("\n".join(lines) + "\n")
    return path


def demo(children, out, arch, *extra, name="demo", duration=25):
    return children.demo(out, "--application", "delivery", "--architecture", arch, "--duration",
                         duration, "--fail", "none", "--no-plots", *extra, name=name)


def duration_for(n):
    """The burst enters when the submitter gets there, some wall seconds into a run at speed 1
    (3.7–6 s of simulated time here): 25 s leaves a burst of 10 time to be served, 40 s one of
    200 (SSI's rounds award one task each, two ticks apart; MinSum gives most to one robot)."""
    return 25 if n <= 10 else 40


# CBBA's first decision over the burst costs each robot 1.6-1.9 CPU-s: 39.4 s of wall at load 25,
# past lockstep's 30 s timeout, and the run was given up as inexact (an xfail until 2026-12-08);
# lockstep now waits for a participant still computing (docs/architecture.md, "Lockstep")
KNOWN: dict[str, str] = {
    # found 2026-12-08 at b6616d1 (load ≈ 10): the run is complete and exact, 190 decisions, and
    # not one of the 200 submitted tasks is ever assigned (robots 3 and 5 idle throughout); a
    # burst of 10 under TeSSI is served. Open in issue 50's closing note
    "tessi": "TeSSI assigns none of a burst of 200 submitted tasks (a burst of 10 is served)",
}


def cases():
    for arch, a in architectures().items():
        if not a.takes_submitted:
            continue
        if arch == "central":
            yield pytest.param(arch, 10, id="central-10")  # the CI case
        marks = (pytest.mark.slow,) + ((pytest.mark.xfail(reason=KNOWN[arch], strict=False),)
                                       if arch in KNOWN else ())
        yield pytest.param(arch, 200, marks=marks, id=f"{arch}-200")


@pytest.mark.timeout(600)
@pytest.mark.parametrize("arch, n", list(cases()))
def test_a_burst_and_a_cancellation_from_other_terminals_are_accounted_for_and_replay(
        children, tmp_path, arch, n):
    endpoint = f"tcp/127.0.0.1:{free_port()}"
    live = tmp_path / "live"
    run = demo(children, live, arch, "--speed", "1", "--rendezvous", endpoint,
               duration=duration_for(n))
    run.wait_line(lambda line: endpoint in line, 60)  # says where the run's bus is
    children.env["MRTA_RENDEZVOUS"] = endpoint  # the other terminals: that variable alone
    # the live picture from another terminal: it learns the submitted tasks from the intake
    watch = children.mrta("supervise", f"delivery_{arch}", "--json", "--sim-time", "--rate",
                          "1", name="supervise")
    watch.wait_line(lambda line: line.startswith("{"), 120)  # it listens (docs/tasks.md)
    submit = children.mrta("task", "submit", "--file", str(burst_file(tmp_path / "b.yaml", n)),
                           "--timeout", "120", name="submit")
    assert submit.wait(180) == 0, submit.stderr[-5:]
    accepted = [line for line in submit.stdout if " accepted at " in line]
    assert len(accepted) == n, submit.stdout[-5:]
    # an urgent task, far from the burst's grid: priority puts it ahead of the burst
    # (answered at the run's next step: after the burst, lockstep waits for the robots' first
    # decision over it — CBBA's took 39 s of wall at load 25 — so not within the default 30 s)
    urgent = children.mrta("task", "submit", "u1", "--set", "position=[-4.0,3.0]",
                           "--priority", "9", "--timeout", "120", name="urgent")
    assert urgent.wait(180) == 0, urgent.stderr[-5:]
    cancel = children.mrta("task", "cancel", "t3", "--as", "dispatcher2", "--timeout", "120",
                           name="cancel")
    assert cancel.wait(180) == 0 and " accepted at " in cancel.stdout[-1], cancel.stderr[-5:]
    bad = children.mrta("task", "submit", "x1", "--set", "positon=[1,2]", name="bad")
    assert bad.wait(120) == 2 and "did you mean 'position'" in bad.stderr[-1], bad.stderr
    listing = children.mrta("task", "list", "--json", name="list")
    assert listing.wait(120) == 0
    assert len(json.loads(listing.stdout[-1])) == n + 1
    shown = json.loads(watch.wait_line(lambda line: '"u1"' in line and '"s0"' in line, 120))
    assert {"s0", "u1", "t1"} <= {t["id"] for t in shown["tasks"]}
    watch.stop()
    assert not [line for line in watch.stdout if '"unknown_task"' in line], \
        [line for line in watch.stdout if '"unknown_task"' in line][:1]
    summary = run.summary(400)
    assert any(line.strip().startswith("submitted at run time:") for line in run.stdout)
    assert summary["run_status"] == "complete" and summary["lockstep_exact"]
    runtime = summary["tasks_at_run_time"]
    rows = {r["id"]: r for r in runtime["tasks"]}
    assert len(rows) == n + 2 and {r["state"] for r in rows.values()} <= STATES
    assert sum(runtime["counts"].values()) == n + 2
    assert rows["t3"]["cancelled_at"] is not None and rows["s0"]["entered_at"] is not None
    assert runtime["served_after_cancel"] == []  # withdrawn from whoever held it
    # submitted tasks are served, not only accounted for; the urgent one among the first
    assert runtime["counts"]["served"] >= 3, runtime["counts"]
    assert rows["u1"]["state"] == "served", rows["u1"]
    served_at = sorted(r["served_at"] for r in rows.values() if r["state"] == "served")
    assert rows["u1"]["served_at"] <= served_at[min(len(served_at) - 1, 4)], served_at
    # the malformed one is refused, counted and listed, never entered
    assert "x1" not in rows and any(r["receiver"] == "tasks" and r["reason"] == "malformed"
                                    for r in summary["refused"])
    assert summary["metrics"]["submitted"] == n + 2
    changes = summary["instance"]["submitted"]
    assert len(changes) == n + 2 and changes[-1]["op"] == "cancel"
    recorded = [r for r in read_recording(live / "run.mcap") if r[0] == "tasks/change"]
    assert len(recorded) == n + 2  # the recording holds what entered too

    again = tmp_path / "again"  # the summary's own instance, run again (no rendezvous)
    replay = demo(children, again, arch, "--speed", "0", "--instance", live / "summary.json",
                  name="again", duration=duration_for(n)).summary(400)
    assert replay["instance"]["submitted"] == changes
    assert replay["lockstep_exact"], (replay["run_status"], replay.get("lockstep"))
    # the same allocation records: every task to the same robot, in the same order, at the
    # same instants (a robot's clock watchdog stopped it while lockstep waited for a slow
    # process, at a wall instant: the live run drifted from its replay by a tick or two)
    assert replay["allocation"] == summary["allocation"]
    assert replay["tasks_at_run_time"] == runtime  # entered, cancelled, served: when, by whom
    assert run_metrics(replay, summary) == run_metrics(summary, replay)


def run_metrics(summary: dict, other: dict) -> dict:
    """The summary's metrics less what measures the machine, and less the references when
    either run's search was stopped by its time cap (then the machine's speed chose them). A
    search ended by its solution count is a function of the instance alone — the references
    of the same 205 tasks once differed between a run and its replay (13,345 against 13,039),
    and OR-Tools' per-neighbourhood wall limit is now the cap (routing.search_parameters)."""
    capped = any(r["stopped_by_time_limit"] for s in (summary, other)
                 for r in s["objectives"]["reference"].values())
    return {k: v for k, v in summary["metrics"].items() if k not in MACHINE_TIME
            and not (capped and (k.startswith(("reference_", "gap_")) or k == "served_gap"))}


@pytest.mark.slow
@pytest.mark.timeout(300)
@pytest.mark.parametrize("arch", [a for a, c in architectures().items() if not c.takes_submitted])
def test_an_architecture_that_grows_no_task_refuses_submissions_from_other_terminals(
        children, tmp_path, arch):
    """ALLIANCE, MURDOCH: the run's intake refuses every submission with the reason, takes a
    cancellation, and the summary counts the refusals (nothing entered)."""
    endpoint = f"tcp/127.0.0.1:{free_port()}"
    run = demo(children, tmp_path / "live", arch, "--speed", "1", "--rendezvous", endpoint)
    run.wait_line(lambda line: endpoint in line, 60)
    children.env["MRTA_RENDEZVOUS"] = endpoint
    submit = children.mrta("task", "submit", "n1", "--set", "position=[1.0,2.0]", name="submit")
    assert submit.wait(120) == 2
    assert "refused: closed: " in submit.stderr[-1] and architectures()[arch].title \
        in submit.stderr[-1], submit.stderr[-3:]
    cancel = children.mrta("task", "cancel", "t3", name="cancel")
    assert cancel.wait(120) == 0, cancel.stderr[-5:]
    summary = run.summary(400)
    assert [r["id"] for r in summary["tasks_at_run_time"]["tasks"]] == ["t3"]
    assert any(r["receiver"] == "tasks" and r["reason"] == "closed" for r in summary["refused"])
