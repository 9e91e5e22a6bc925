"""The overlap check on a summary alone (docs/delivery.md, "Allocation records"): a forged
summary whose records have two robots executing one task at once is caught, with the robots and
the interval; a handover within a tick and one robot's own stretches are not overlaps."""

from __future__ import annotations

import msgspec

from mrta_delivery.mission import DeliverySections
from mrta_delivery.objectives import overlaps

INSTANCE = {
    "application": "delivery",
    "robots": {"robot1": {"start": [0.0, 0.0], "speed": 0.5, "capabilities": []},
               "robot2": {"start": [4.0, 0.0], "speed": 0.5, "capabilities": []}},
    "tasks": {"t1": {"position": [1.0, 0.0], "service": 2.0},
              "t2": {"position": [3.0, 0.0], "service": 2.0}},
}


def stretch(task, robot, started, done, ended, reason):
    return {"task": task, "robot": robot, "assigned_at": started, "started_at": started,
            "done_at": done, "ended_at": ended, "reason": reason}


def sections(allocation) -> DeliverySections:
    """What `read_summary` gives of a summary's delivery sections (the same type, converted)."""
    return msgspec.convert({"instance": INSTANCE, "allocation": allocation}, DeliverySections)


def test_a_forged_summary_with_two_robots_on_one_task_is_an_overlap():
    forged = sections([stretch("t1", "robot1", 1.0, 10.0, 10.1, "done"),
                       stretch("t1", "robot2", 5.0, 12.0, 12.1, "done"),
                       stretch("t2", "robot2", 0.0, None, 4.9, "released")])
    (o,) = overlaps(forged.allocation)
    assert (o.task, set(o.robots), o.start, o.end) == ("t1", {"robot1", "robot2"}, 5.0, 10.0)
    assert o.to_json() == {"task": "t1", "robots": list(o.robots), "from": 5.0, "to": 10.0}


def test_a_lost_stretch_counts_until_it_ended():
    forged = sections([stretch("t1", "robot1", 1.0, None, 8.0, "lost"),
                       stretch("t1", "robot2", 6.0, 11.0, 11.1, "done")])
    (o,) = overlaps(forged.allocation)
    assert (o.start, o.end) == (6.0, 8.0)


def test_a_handover_within_a_tick_and_one_robots_own_stretches_are_no_overlap():
    fine = sections([stretch("t1", "robot1", 1.0, None, 5.0, "stalled"),
                     stretch("t1", "robot2", 5.05, 9.0, 9.1, "done"),
                     stretch("t2", "robot2", 0.0, None, 3.0, "released"),
                     stretch("t2", "robot2", 2.0, 8.0, 8.1, "done")])
    assert overlaps(fine.allocation) == []
