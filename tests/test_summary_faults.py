"""What a summary says of faults (issue 51.2/51.5): every subject fault of a combined spec is
reported (not only the first), and the robots a decider left out of its plan — a stall the
dispatcher declared — are named, from when until when."""

from __future__ import annotations

import io

from rich.console import Console

from mrta_agent.central.architecture import CENTRAL, DISPATCHER
from mrta_agent.central.dispatcher import STALLED
from mrta_supervisor.mission import summary as summary_module
from mrta_supervisor.mission.cli import print_summary
from mrta_supervisor.mission.ground_truth import declared
from mrta_supervisor.mission.summary import Declared, Decisions, FailureReport, Summary
from mrta_zenoh.architectures import Decision
from mrta_zenoh.messages import Header
from tests.test_central_trust import progress, started


def summary(**kw) -> Summary:
    base = dict(mission="delivery", application="delivery_central", architecture="central",
                duration=60.0, speed=0.0, seed=1, wall_seconds=1.0, robots=["robot1"],
                who_did_what={"robot1": []}, first_full_allocation=None, coverage={},
                messages=summary_module.MessageRates(1.0, 0.5, "central"), output="o",
                files=[])
    base.update(kw)
    return Summary(**base)


def printed(s: Summary) -> str:
    out = io.StringIO()
    print_summary(Console(file=out, width=300), s, "Delivery mission", "central", [])
    return out.getvalue()


def test_stretches_out_of_the_plan_run_from_the_first_decision_to_the_first_without_it():
    found = [Decision(DISPATCHER, 1.0, 1.0), Decision(DISPATCHER, 12.0, 1.0, out=(
        ("robot2", "stalled"),)), Decision(DISPATCHER, 14.0, 1.0, out=(
            ("robot2", "stalled"), ("robot3", "silent"))),
        Decision(DISPATCHER, 20.0, 1.0, out=(("robot3", "crashed"),))]
    assert declared(found) == [Declared("robot2", "stalled", 12.0, 20.0, DISPATCHER),
                               Declared("robot3", "silent", 14.0, 20.0, DISPATCHER),
                               Declared("robot3", "crashed", 20.0, None, DISPATCHER)]


def test_the_dispatchers_decisions_say_who_is_out_of_the_plan_and_why():
    """A robot that has a task and does not progress is declared stalled: the decision that
    re-plans its tasks says so (Plan.out), and the one that takes it back does not."""
    d = started(timeout=2.0)
    v, now, plans = d.sent["robot1"].version, 0.1, []
    while d.robots["robot1"].lost is None:
        d.hear("progress", "robot1", progress("t1", ("t1", "t2", "t4"), v, 0.0), now)
        d.hear("progress", "robot2", progress("", (), d.sent["robot2"].version, 10.0), now)
        plans += [s for s in d.tick(now) if s.kind == "plan"]
        now = round(now + 0.1, 1)
    assert d.robots["robot1"].lost == STALLED and plans[-1].fields["out"] == ("robot1:stalled",)
    message = plans[-1].message(CENTRAL.messages, Header(DISPATCHER, now, 1))
    assert CENTRAL.decision(DISPATCHER, "dispatcher/central/plan", message).out == (
        ("robot1", "stalled"),)
    d.hear("progress", "robot1", progress("", (), d.sent["robot1"].version, 0.5), now)
    (back,) = [s for s in d.tick(now) if s.kind == "plan"]
    assert back.fields["out"] == ()


def test_the_printed_summary_names_every_fault_and_every_declared_stall():
    s = summary(failure=FailureReport("robot4", 5.0, fault="stall", task="t3",
                                      taken_over_by="robot3", takeover_seconds=10.2),
                other_failures=[FailureReport("robot1", 8.0, fault="crash", task="t1"),
                                FailureReport("robot2", None, fault="partition")],
                decisions=Decisions(4, 1.0, 2.0, "minsum", declared=[
                    Declared("robot4", "stalled", 15.1, None, DISPATCHER),
                    Declared("robot1", "crashed", 8.1, None, DISPATCHER)]))
    text = printed(s)
    assert "robot4 stalled at 5.0 s while doing t3; robot3 took over after 10.20 s" in text
    assert "robot1 killed at 8.0 s; task t1 was not taken over before the end" in text
    assert "robot2: partition never struck" in text
    assert "dispatcher declared robot4 stalled at 15.1 s (to the end)" in text
    assert "dispatcher declared robot1 crashed at 8.1 s (to the end)" in text
    data = summary_module.summary_json(s).decode()
    assert '"other_failures"' in data and '"declared"' in data
    assert '"other_failures"' not in summary_module.summary_json(summary()).decode()


def test_a_process_that_ended_before_the_run_did_marks_its_loss_or_adds_one():
    """A SIGKILLed dispatcher or recorder (issue 51.5): its token's loss says how it ended, or
    one is added; the run is then disturbed (incomplete for the recorder), with that cause."""
    from mrta_supervisor.mission.run_watch import ended_early, run_status
    from mrta_supervisor.mission.summary import Disturbance, run_problem

    seen = [Disturbance("dispatcher", 12.0), Disturbance("robot2", 3.0, 4.0)]
    out = ended_early(seen, {"dispatcher": "killed by SIGKILL",
                             "recorder": "killed by SIGKILL"}, 30.0)
    assert out == [Disturbance("dispatcher", 12.0, ended="killed by SIGKILL"),
                   Disturbance("robot2", 3.0, 4.0),
                   Disturbance("recorder", 30.0, ended="killed by SIGKILL")]
    assert seen[0].ended is None  # the watch's own list is left as it was
    assert run_status(out[:2], 30.0, 30.0) == "disturbed"
    assert run_status(out, 30.0, 30.0) == "incomplete"
    s = summary(run_status="disturbed", disturbances=out[:2], lockstep_exact=False)
    assert run_problem(s) == (
        "a process of the run ended before the run did (dispatcher killed by SIGKILL at 12 s); "
        "a process of the run was stopped or cut off (robot2 lost its token at 3 s, back at "
        "4 s): the run is not what its seed gives")


def test_names_from_the_bus_are_printed_as_they_are_never_read_as_markup():
    """A Round's `out` (`[/bold]:stalled`), a stranger's token, a refusal's sender: each comes
    from the bus, and rich read "[/bold]" as a closing tag — MarkupError after the run, no
    summary printed."""
    s = summary(strangers=["[/bold]"], refused=[
        summary_module.Refusal("robot1", "[/red]", "bids", "stamp_ahead", 1, True)],
        decisions=Decisions(1, 1.0, 1.0, "minsum", declared=[
            Declared("[/x]", "stalled", 1.0, None, "robot1")]))
    text = printed(s)
    assert "robot1 declared [/x] stalled at 1 s" in text
    assert "[/bold]" in text and "of [/red]: stamp_ahead" in text


def test_a_messages_out_list_is_read_bounded_and_escaped():
    from mrta_zenoh.architectures import MAX_OUT, declared_out
    assert declared_out(("robot2:stalled", "nothing", "\x1b[2J:silent")) == (
        ("robot2", "stalled"), ("\\x1b[2J", "silent"))
    assert len(declared_out([f"robot{i}:stalled" for i in range(10_000)])) == MAX_OUT

