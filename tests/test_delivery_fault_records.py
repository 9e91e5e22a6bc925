"""Allocation records under a role-named fault (docs/delivery.md, "Allocation records"): the
analysis reads the fault as the robot it struck, so a stalled robot's stretches end at its
stall with reason `stalled` — though it goes on saying it holds its tasks — and a crashed
robot's at its crash with `lost`; the teammate that takes a task over is no overlap."""

from __future__ import annotations

import msgspec

from mrta_agent.route.messages import Progress
from mrta_agent.ssi.architecture import SSI
from mrta_delivery.instance import InstanceBody
from mrta_delivery.metrics import allocation_log
from mrta_delivery.objectives import overlaps
from mrta_supervisor.mission.roles import as_struck
from mrta_zenoh.codec import encode, encoding_for
from mrta_zenoh.failure import parse_faults
from mrta_zenoh.fault_roles import Assigned, assigned_key
from mrta_zenoh.messages import Header

PARAMS = msgspec.convert({
    "robots": {"robot1": {"start": [0.0, 0.0], "speed": 0.5},
               "robot2": {"start": [4.0, 0.0], "speed": 0.5}},
    "tasks": {"t1": {"position": [1.0, 0.0], "service": 2.0},
              "t2": {"position": [3.0, 0.0], "service": 2.0}}}, InstanceBody)


def progress(robot: str, at: float, task: str, queue: tuple[str, ...]):
    msg = Progress(Header(robot, at, int(at * 10)), task, "", queue, (), 0.0, 0.0, 0.0)
    return (f"{robot}/ssi/progress", encoding_for(Progress.TYPE_NAME), int(at * 1e9),
            encode(msg))


def recording() -> list:
    """robot1 is first assigned at 0.5, sets off to t2 (t1 behind it) and keeps reporting so
    every second, to 20 s; robot2 takes t2 over at 12 and serves it to 20."""
    first = Assigned(Header("robot1", 0.5, 1), "t1")
    out = [(assigned_key("robot1"), encoding_for(Assigned.TYPE_NAME), int(0.5e9), encode(first))]
    for i in range(1, 21):
        out.append(progress("robot1", float(i), "t2", ("t2", "t1")))
        if i >= 12:
            out.append(progress("robot2", float(i) + 0.05, "t2", ("t2",)))
    return out


def test_a_stalled_robot_s_stretches_end_at_its_stall_and_no_takeover_is_an_overlap():
    records = recording()
    faults = as_struck(parse_faults("stall:@first@5"), records)
    assert [(f.robot, f.at) for f in faults.failures] == [("robot1", 5.0)]
    log = allocation_log(records, SSI, PARAMS.problem(), 20.0, faults)
    mine = [e for e in log if e.robot == "robot1"]
    assert {e.task for e in mine} == {"t1", "t2"}
    assert all(e.ended_at <= 5.0 and e.reason == "stalled" for e in mine), mine
    assert overlaps(log) == []
    # read with the role unresolved (as the analysis did), robot1 held t2 beside robot2
    unresolved = allocation_log(records, SSI, PARAMS.problem(), 20.0,
                                parse_faults("stall:@first@5"))
    assert overlaps(unresolved)


def test_a_crashed_robot_s_stretches_end_at_its_crash_as_lost():
    records = recording()
    log = allocation_log(records, SSI, PARAMS.problem(), 20.0,
                         as_struck(parse_faults("crash:@first@5"), records))
    mine = [e for e in log if e.robot == "robot1"]
    assert mine and all(e.ended_at <= 5.0 and e.reason == "lost" for e in mine), mine


def test_a_robot_holding_while_its_dispatcher_is_silent_is_no_overlap():
    """central under a partition (issue 51.2): robot1, cut off, holds t2 (stands still, its
    dispatcher silent past its lease) while the dispatcher gives t2 to robot2 — both said it
    was theirs, and the summary counted an overlap. A holding robot serves nothing."""
    from mrta_agent.central.architecture import CENTRAL

    def report(robot: str, at: float, holding: bool) -> tuple:
        msg = Progress(Header(robot, at, int(at * 10)), "t2", "", ("t2",), (), 0.0, 0.0, 0.0,
                       1, holding)
        return (f"{robot}/central/progress", encoding_for(Progress.TYPE_NAME), int(at * 1e9),
                encode(msg))

    records = [report("robot1", float(i), holding=i >= 6) for i in range(1, 21)]
    records += [report("robot2", i + 0.05, holding=False) for i in range(10, 21)]
    records.sort(key=lambda r: r[2])
    log = allocation_log(records, CENTRAL, PARAMS.problem(), 20.0)
    assert not overlaps(log)
    first = next(e for e in log if e.robot == "robot1")
    assert first.task == "t2" and first.ended_at == 6.0
