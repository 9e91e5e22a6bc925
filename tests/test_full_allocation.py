"""`first_full_allocation` (supervisor/mission/runner.py) is measured only for missions whose tasks all
need a robot at once: patrol's, not delivery's, whose tasks are served in turn."""

from __future__ import annotations

from mrta_delivery.mission import DELIVERY
from mrta_supervisor.mission.analysis import full_allocation
from mrta_supervisor.mission.hook import missions


def patrol():
    return missions()["patrol"].load()


INTERVALS = {"robot1": [("t1", 0.5, 9.0)], "robot2": [("t2", 1.5, 4.0), ("t3", 5.0, 9.0)]}


def test_patrol_measures_when_every_task_was_first_held_at_once():
    # t1 from 0.5, t2 from 1.5 to 4.0, t3 only from 5.0: t1 and t2 both held at 1.5
    assert full_allocation(patrol(), INTERVALS, ["t1", "t2"]) == 1.5
    assert full_allocation(patrol(), INTERVALS, ["t1", "t2", "t3"]) is None  # never all three


def test_delivery_leaves_it_out_even_when_every_task_was_held_at_once():
    assert full_allocation(DELIVERY, INTERVALS, ["t1", "t2"]) is None
