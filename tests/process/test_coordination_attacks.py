"""A forger on the bus of a real `mrta demo` (issue 51): one session on the run's rendezvous
(the runner logs where it is) publishing, once, what the hostile probe sent under the demo's
keys — copied from a real message of the run (tests/procs/coordination_forger.py). Every task
of the default delivery instance is still delivered, the run does not stop, and the summary
names what was refused and calls the run disturbed (not complete and exact, and not the
machine's fault). The in-process tests of each rule: tests/test_central_trust.py,
tests/test_believed_claims.py.

The CI tier runs two attacks: the delivery `done` (every architecture's, under ALLIANCE) and
CBBA's `Bids` (a route-family architecture's own message; CBBA's one cross-process run in CI):
the process tests of "a message believed only for what its sender can claim" and "refused
traffic in the summary" (≈ 10–14 CPU-s each). Central's `Progress` and SSI's `Round` are `slow`:
their rules are proved in-process (tests/test_central_trust.py, tests/test_believed_claims.py),
the path from a refusal to the summary is the same, and central and SSI run across processes in
CI elsewhere (test_golden_summaries[central-stall], test_windows_multiprocess[ssi]); a stranger's
lockstep token, a forged token under a crashed member's name (lockstep/ended.py) and MURDOCH's
forged earlier claim (tests/test_murdoch_trust.py) are `slow` too."""

from __future__ import annotations

import re

import pytest

pytestmark = [pytest.mark.multiprocess]

TASKS = "t1,t2,t3,t4"


def forger_beside(children, demo, mode: str, arg: str, name: str = "forger"):
    """tests/procs/coordination_forger.py started on the demo's rendezvous once its processes
    meet (the line that names it): the forger, not yet waited for."""
    line = demo.wait_stderr(lambda s: "processes meet at" in s, 120)
    rendezvous = re.search(r"tcp/127\.0\.0\.1:\d+", line).group(0)
    return children.python("coordination_forger.py", mode, arg, rendezvous, name=name)


def attacked_demo(children, tmp_path, arch: str, mode: str, arg: str) -> dict:
    out = tmp_path / arch
    demo = children.demo(out, "--application", "delivery", "--architecture", arch, "--duration",
                         "60", "--no-plots")
    forger = forger_beside(children, demo, mode, arg)
    forger.wait_json(lambda o: "forged" in o, 120)
    summary = demo.summary(300)
    assert summary["metrics"]["completed"] == summary["metrics"]["tasks"], summary["metrics"]
    assert summary["run_status"] == "disturbed" and summary["lockstep_exact"] is False
    printed = "\n".join(demo.stdout)
    assert "refused:" in printed and "forged coordination traffic" in printed, printed
    return summary


def test_four_dones_from_a_robot_that_never_moved_neither_end_the_run_nor_skip_a_task(
        children, tmp_path):
    """They ended the run at 3.3 s "every task done" with 0/4 delivered (issue 51): every
    teammate and the runner's task watch believed them."""
    s = attacked_demo(children, tmp_path, "alliance", "delivery-done", "robot5")
    refused = {(r["receiver"], r["sender"], r["reason"], r["forged"]) for r in s["refused"]}
    assert {(r, "robot5", "done_not_started", True) for r in ("robot1", "robot2", "robot3",
                                                                  "robot4")} <= refused, refused
    assert ("robot5", "robot5", "own_done_not_said", True) in refused
    assert s["ended_at"] > 10.0 and s["metrics"]["events_refused"] == 4


@pytest.mark.slow
def test_a_progress_saying_every_task_served_neither_stops_the_dispatcher_nor_the_run(
        children, tmp_path):
    """It raised in the dispatcher ("task … is on the routes of …"): exit 1, no summary."""
    s = attacked_demo(children, tmp_path, "central", "central-served", TASKS)
    refused = [(r["receiver"], r["sender"], r["reason"], r["forged"]) for r in s["refused"]]
    assert ("dispatcher", "robot2", "not_granted", True) in refused


@pytest.mark.slow
def test_a_round_numbered_2_62_does_not_stop_ssi(children, tmp_path):
    s = attacked_demo(children, tmp_path, "ssi", "ssi-round", "-")
    assert any(r["reason"] == "round_ahead" and r["sender"] == "robot1" for r in s["refused"])


def test_a_bids_saying_the_tasks_others_won_done_does_not_end_cbba(children, tmp_path):
    s = attacked_demo(children, tmp_path, "cbba", "cbba-done", "4")
    assert any(r["reason"] == "done_not_won" and r["sender"] == "robot2" for r in s["refused"])


@pytest.mark.slow
@pytest.mark.timeout(300)
def test_a_strangers_lockstep_token_is_named_and_neither_waited_for_nor_making_it_inexact(
        children, tmp_path):
    """A participant token under a name that is no process of the run (issue 51.3): the
    simulator, told the run's members, refuses it and never waits for it — it used to wait the
    lockstep timeout, give it up and leave the run inexact, which `mrta experiment` then
    dropped from its statistics. The summary names it apart."""
    out = tmp_path / "run"
    demo = children.demo(out, "--application", "delivery", "--no-plots")
    stranger = forger_beside(children, demo, "participant", "intruder", name="stranger")
    stranger.wait_json(lambda o: "forged" in o, 120)
    s = demo.summary(240)
    assert s["strangers"] == ["intruder"], s.get("strangers")
    assert s["run_status"] == "complete" and s["lockstep_exact"] is True, (
        s["run_status"], s["lockstep_given_up"], s["disturbances"])
    assert s["lockstep_given_up"] == 0 and s["metrics"]["completed"] == s["metrics"]["tasks"]


@pytest.mark.slow
@pytest.mark.timeout(300)
def test_a_token_under_a_crashed_members_name_does_not_stall_the_run(children, tmp_path):
    """A participant token under robot2's own name, declared by a forger beside robot2's:
    Zenoh shows one token per key, so when robot2 crashes the name stays alive, and the
    simulator waited the whole lockstep timeout (30 s) for it, gave it up and left the run
    inexact. The runner tells the simulator which of its processes ended (lockstep/ended.py):
    robot2 is not waited for (nobody is given up), and the summary names the token that
    outlived its process as forged: the run is disturbed (and so not called exact) by the
    forgery, not by a stall."""
    demo = children.demo(tmp_path / "run", "--application", "delivery", "--no-plots",
                         "--duration", "60", "--fail", "crash:robot2@20")
    forger = forger_beside(children, demo, "participant", "robot2")
    forger.wait_json(lambda o: "forged" in o, 120)
    s = demo.summary(240)
    assert s["lockstep_given_up"] == 0, (s["lockstep_given_up"], s["disturbances"])
    refused = {(r["receiver"], r["sender"], r["reason"], r["forged"]) for r in s["refused"]}
    assert ("simulator", "robot2", "outlived_process", True) in refused, refused
    assert s["run_status"] == "disturbed"


@pytest.mark.slow
@pytest.mark.timeout(300)
def test_one_forged_murdoch_claim_with_an_earlier_start_displaces_no_holder(children, tmp_path):
    """A Claim copied from the first holder's, said once under another robot's key with a
    start one second earlier: the holder yielded its task to it, and the task waited for the
    forged 20 s lease. A claim heard once is no contract now: the holder keeps the task, and
    counts the claim that lapsed unrenewed (tests/test_murdoch_trust.py: the rule in process)."""
    demo = children.demo(tmp_path / "run", "--application", "delivery", "--architecture",
                         "murdoch", "--speed", "1", "--no-plots", "--duration", "60")
    forger = forger_beside(children, demo, "murdoch-claim", "-")
    who = forger.wait_json(lambda o: "holder" in o, 120)
    forger.wait_json(lambda o: "forged" in o, 60)
    s = demo.summary(240)
    assert s["metrics"]["completed"] == s["metrics"]["tasks"], s["metrics"]
    refused = {(r["receiver"], r["sender"], r["reason"]) for r in s["refused"]}
    assert (who["holder"], who["as"], "claim_not_renewed") in refused, refused
    served = [x["task"] for x in s["who_did_what"][who["holder"]]]
    assert served.count(who["task"]) == 1, s["who_did_what"]

