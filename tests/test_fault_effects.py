"""The summary's `fault_effects`: each robot's latest tally before the run's end, summed over
the team; forged, stray, late and malformed tallies do not count."""

from __future__ import annotations

from mrta_supervisor.mission.fault_effects import fault_effects
from mrta_supervisor.experiment.results import kind
from mrta_supervisor.mission.summary import MessageRates, Summary, flat_metrics
from mrta_zenoh.codec import encode
from mrta_zenoh.fault_tally import FaultTally, tally_key
from mrta_zenoh.messages import Header

ENC = "application/msgpack;mrta_msgs/FaultTally"


def tally(robot: str, stamp: float, frame: str | None = None, **counts):
    msg = FaultTally(Header(frame or robot, stamp, 1), **counts)
    return (tally_key(robot), ENC, 0, encode(msg))


def test_the_latest_tally_of_each_robot_before_the_end_is_summed():
    records = [
        tally("robot1", 1.0, lost=3), tally("robot1", 2.0, lost=5, delayed=9),
        tally("robot2", 1.5, cut_off=4),
        tally("robot2", 0.5, cut_off=1),             # older, recorded later: not the latest
        tally("robot1", 9.0, lost=50),               # after the end
        tally("robot3", 1.0, frame="robot9", lost=70),  # forged: its key says robot3
        tally("robot8", 1.0, lost=80),               # not on the team
        (tally_key("robot3"), ENC, 0, b"\xc1junk"),  # malformed: dropped
        ("robot3/faults/tally/x", ENC, 0, encode(FaultTally(Header("robot3", 1.0, 1), lost=1))),
    ]
    got = fault_effects(records, ["robot1", "robot2", "robot3"], until=5.0)
    assert got == {"lost": 5, "delayed": 9, "cut_off": 4, "out_of_range": 0}
    assert fault_effects(records[:1], ["robot2"], until=5.0) == {}  # nobody said one


def test_results_rows_carry_each_cause_as_a_measure():
    s = Summary(mission="delivery", application="delivery_ssi", architecture="ssi",
                duration=60.0, speed=0.0, seed=1, wall_seconds=1.0, robots=["robot1"],
                who_did_what={"robot1": []}, first_full_allocation=None, coverage={},
                messages=MessageRates(1.0, 0.5, "ssi"), output="o", files=[],
                fault_effects={"lost": 7, "delayed": 0, "cut_off": 2, "out_of_range": 0})
    row = flat_metrics(s)
    assert (row["faults.lost"], row["faults.cut_off"], row["faults.out_of_range"]) == (7, 2, 0)
    assert kind("faults.lost") == "measure"  # not a parameter splitting the cells
    s.fault_effects = {}
    assert flat_metrics(s)["faults.lost"] == 0


def test_the_fault_channels_own_words_are_not_the_architectures_traffic():
    from mrta_supervisor.mission.analysis import is_traffic
    assert not is_traffic("robot1/faults/tally") and not is_traffic("robot1/faults/assigned")
    assert is_traffic("robot1/alliance/inter_robot_communication")


def test_a_report_shows_the_faults_dose_only_when_asked(tmp_path):
    from mrta_supervisor.experiment.report import default_metrics
    from mrta_supervisor.experiment.results import read_results
    f = tmp_path / "results.csv"
    f.write_text("run,seed,status,failure,faults.lost,messages_per_second,takeover_seconds\n"
                 "1,1,ok,loss:0.2,12,3.0,2.5\n")
    assert default_metrics(read_results(f)) == ["takeover_seconds"]


# ------------------------------------------------------------------ what processes refused
def refusal_tally(name: str, stamp: float, entries: dict, frame: str | None = None):
    from mrta_zenoh.refusal_tally import refused_key, tally as refusal
    msg = refusal(Header(frame or name, stamp, 1), entries)
    return (refused_key(name), "application/msgpack;mrta_msgs/RefusedTally", 0, encode(msg))


def test_what_each_process_refused_is_listed_forged_first_and_makes_the_run_disturbed():
    from mrta_supervisor.mission.fault_effects import refused_traffic
    from mrta_supervisor.mission.cli import refused_lines
    from mrta_supervisor.mission.summary import DISTURBED, run_problem
    records = [
        refusal_tally("dispatcher", 1.0, {("progress", "robot2", "not_granted", True): 1}),
        refusal_tally("dispatcher", 3.0, {("progress", "robot2", "not_granted", True): 3,
                                          ("progress", "robot1", "served_twice", False): 1}),
        refusal_tally("robot1", 2.0, {("queue", "dispatcher", "version_ahead", True): 9},
                      frame="robot2"),                    # its header names another: dropped
        refusal_tally("robot7", 2.0, {("bids", "robot1", "done_not_won", True): 9}),  # no process
        tally("robot1", 1.0, lost=3),                     # a fault tally: not a refusal
    ]
    refused = refused_traffic(records, ["robot1", "robot2", "dispatcher"])
    assert [(r.receiver, r.sender, r.reason, r.count, r.forged) for r in refused] == [
        ("dispatcher", "robot2", "not_granted", 3, True),
        ("dispatcher", "robot1", "served_twice", 1, False)]
    s = Summary(mission="delivery", application="delivery_central", architecture="central",
                duration=60.0, speed=0.0, seed=1, wall_seconds=1.0, robots=["robot1"],
                who_did_what={"robot1": []}, first_full_allocation=None, coverage={},
                messages=MessageRates(1.0, 0.5, "central"), output="o", files=[],
                refused=refused, run_status=DISTURBED, lockstep_exact=False)
    problem = run_problem(s)
    assert "forged coordination traffic" in problem and "not_granted" in problem
    assert "busy" not in problem  # not the machine's load
    lines = refused_lines(s)
    assert lines[0] == "refused: 4 samples or claims (3 forged)"
    assert "dispatcher refused 3 progress of robot2: not_granted (forged)" in lines[1]
    from mrta_supervisor.mission.analysis import is_traffic
    assert not is_traffic("dispatcher/refused/tally")


def test_a_task_reported_served_twice_makes_the_run_disturbed_and_says_so():
    """A real network cut can let two robots serve one task (issue 51): the dispatcher hears the
    second report (`served_twice`, no forgery); the run is then never "complete", and its
    problem line says a task was served twice."""
    from mrta_supervisor.mission.summary import (COMPLETE, DISTURBED, INCOMPLETE, Refusal,
                                                 refused_status, run_problem)
    twice = [Refusal("dispatcher", "robot4", "progress", "served_twice", 1, False)]
    stranger = [Refusal("robot1", "robot9", "bids", "off_roster", 2, False)]
    assert refused_status(COMPLETE, twice) == DISTURBED
    assert refused_status(COMPLETE, stranger) == COMPLETE  # judges nothing
    assert refused_status(INCOMPLETE, twice) == INCOMPLETE
    s = Summary(mission="delivery", application="delivery_central", architecture="central",
                duration=60.0, speed=0.0, seed=1, wall_seconds=1.0, robots=["robot4"],
                who_did_what={"robot4": []}, first_full_allocation=None, coverage={},
                messages=MessageRates(1.0, 0.5, "central"), output="o", files=[],
                refused=twice, run_status=DISTURBED, lockstep_exact=False)
    assert run_problem(s) == ("a task was reported served by a second robot — served twice "
                              "(dispatcher heard 1 from robot4): the run is not what its seed "
                              "gives")


def test_an_inexact_lockstep_run_does_not_blame_the_machine_alone():
    """NOT EXACT blamed the machine's load whatever caused it (issue 51); a forger's StepDone
    claims in a participant's name are forgiven the same way, and the line says so."""
    from mrta_supervisor.mission.summary import COMPLETE, run_problem
    s = Summary(mission="delivery", application="delivery", architecture="alliance",
                duration=60.0, speed=0.0, seed=1, wall_seconds=1.0, robots=["robot1"],
                who_did_what={"robot1": []}, first_full_allocation=None, coverage={},
                messages=MessageRates(1.0, 0.5, "alliance"), output="o", files=[],
                run_status=COMPLETE, lockstep_exact=False, lockstep_forgiven=1)
    problem = run_problem(s)
    assert "busy" in problem and "forger" in problem, problem
