"""SSI and CBBA on a secured fleet (issue 51): `mrta secure init` then `mrta demo --secure`, the
default delivery instance, every process with its own certificate through the fleet's router.
robot2's own certificate (tests/procs/coordination_forger.py with FLEET/robot2.json5: a
certified robot, under its own key, which the router lets through) forges once what took the
open-bus probe to 0/4 delivered: SSI — a `Bid` to the auctioneer saying every task served;
CBBA — a `Bids` saying every task done. Every task is still delivered, and the summary counts
the refused claims and calls the run disturbed."""

from __future__ import annotations


import pytest
from click.testing import CliRunner

from mrta_zenoh.cli.main import cli
from tests.harness.helpers import free_port

pytestmark = [pytest.mark.multiprocess, pytest.mark.slow]

ROBOTS = ("robot1", "robot2", "robot3", "robot4", "robot5")


def fleet(tmp_path, *extra: str):
    folder = tmp_path / "fleet"
    result = CliRunner().invoke(cli, ["secure", "init", str(folder), *sum(
        (["--robot", r] for r in ROBOTS), []), "--observer", "supervisor", "--observer",
        "recorder", "--endpoint", f"tls/127.0.0.1:{free_port()}", *extra])
    assert result.exit_code == 0, result.output
    return folder


def secured_demo(children, tmp_path, arch: str, mode: str) -> dict:
    folder = fleet(tmp_path)
    out = tmp_path / arch
    demo = children.demo(out, "--application", "delivery", "--architecture", arch, "--secure",
                         folder, "--duration", "60", "--no-plots")
    demo.wait_stderr(lambda s: "processes meet at tls/" in s, 120)
    forger = children.python("coordination_forger.py", mode, "4", folder / "robot2.json5",
                             name="forger")
    forger.wait_json(lambda o: "forged" in o, 180)
    summary = demo.summary(300)
    assert summary["metrics"]["completed"] == summary["metrics"]["tasks"] == 4, summary["metrics"]
    assert summary["run_status"] == "disturbed"
    return summary


@pytest.mark.timeout(420)
def test_a_task_submitted_through_a_secured_fleets_router_is_served(children, tmp_path):
    """`mrta secure init --submitter ops` then `mrta demo --secure`: the run starts its intake
    (the fleet holds its certificate) and goes on to its duration; a task submitted under ops's
    certificate through the fleet's router is accepted and served, and the run stays complete
    and exact (issue 51: `--secure` with `--submitter` was untested, and a secured run of an
    instance with no schedule had no intake: the submission found none). Speed 1, so that the
    submission — whenever its process starts — enters while the run has most of its 60 s
    left."""
    folder = fleet(tmp_path, "--submitter", "ops")
    out = tmp_path / "ssi"
    demo = children.demo(out, "--application", "delivery", "--architecture", "ssi", "--secure",
                         folder, "--duration", "60", "--speed", "1", "--no-plots")
    demo.wait_line(lambda s: "tasks at run time: a submitter" in s, 120)  # it says how
    demo.wait_stderr(lambda s: "processes meet at tls/" in s, 120)  # the router is up
    submit = children.mrta("task", "submit", "n1", "--set", "position=[1.0,2.0]", "--as", "ops",
                           "--zenoh-config", folder / "ops.json5", "--timeout", "120",
                           name="submit")
    assert submit.wait(180) == 0 and " accepted at " in submit.stdout[-1], submit.stderr[-5:]
    s = demo.summary(300)
    rows = {r["id"]: r for r in s["tasks_at_run_time"]["tasks"]}
    assert rows["n1"]["state"] == "served", rows
    assert s["metrics"]["completed"] == s["metrics"]["tasks"] == 5, s["metrics"]
    assert s["run_status"] == "complete" and s["lockstep_exact"], s["disturbances"]


@pytest.mark.timeout(420)
def test_a_certified_robots_bid_saying_every_task_served_leaves_ssi_delivering_all(
        children, tmp_path):
    s = secured_demo(children, tmp_path, "ssi", "ssi-served")
    refused = {(r["receiver"], r["sender"], r["reason"], r["forged"]): r for r in s["refused"]}
    assert ("robot1", "robot2", "not_held", True) in refused, s["refused"]  # the auctioneer


@pytest.mark.timeout(420)
def test_a_certified_robots_bids_saying_every_task_done_leaves_cbba_delivering_all(
        children, tmp_path):
    s = secured_demo(children, tmp_path, "cbba", "cbba-done-all")
    receivers = {r["receiver"] for r in s["refused"]
                 if (r["sender"], r["reason"], r["forged"]) == ("robot2", "done_not_won", True)}
    assert receivers == {"robot1", "robot3", "robot4", "robot5"}, s["refused"]
