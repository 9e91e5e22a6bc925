"""SSI and CBBA on a secured fleet (issue 51): `mrta secure init` then `mrta demo --secure`, the
default delivery instance, every process with its own certificate through the fleet's router.
robot2's own certificate (tests/procs/coordination_forger.py with FLEET/robot2.json5: a
certified robot, under its own key, which the router lets through) forges once what took the
open-bus probe to 0/4 delivered: SSI — a `Bid` to the auctioneer saying every task served;
CBBA — a `Bids` saying every task done. Every task is still delivered, and the summary counts
the refused claims and calls the run disturbed."""

from __future__ import annotations

import json

import pytest
from click.testing import CliRunner

from mrta_zenoh.cli.main import cli
from tests.harness.helpers import free_port

pytestmark = [pytest.mark.multiprocess, pytest.mark.slow]

ROBOTS = ("robot1", "robot2", "robot3", "robot4", "robot5")


def secured_demo(children, tmp_path, arch: str, mode: str) -> dict:
    folder = tmp_path / "fleet"
    result = CliRunner().invoke(cli, ["secure", "init", str(folder), *sum(
        (["--robot", r] for r in ROBOTS), []), "--observer", "supervisor", "--observer",
        "recorder", "--endpoint", f"tls/127.0.0.1:{free_port()}"])
    assert result.exit_code == 0, result.output
    out = tmp_path / arch
    demo = children.mrta("demo", "--application", "delivery", "--architecture", arch,
                         "--secure", folder, "--duration", "60", "--speed", "0", "--no-live",
                         "--no-plots", "--output", out, name="demo")
    demo.wait_stderr(lambda s: "processes meet at tls/" in s, 120)
    forger = children.python("coordination_forger.py", mode, "4", folder / "robot2.json5",
                             name="forger")
    forger.wait_json(lambda o: "forged" in o, 180)
    assert demo.wait(300) == 0, demo.tail(30)
    summary = json.loads((out / "summary.json").read_text())
    assert summary["metrics"]["completed"] == summary["metrics"]["tasks"] == 4, summary["metrics"]
    assert summary["run_status"] == "disturbed"
    return summary


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
