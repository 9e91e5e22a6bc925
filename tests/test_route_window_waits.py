"""A robot waiting at its task for the window to open, then serving it, is not stalled (issue 49):
the own-route architectures' progress watch (robot_agent/route/own_route.py) counts a teammate
out after `progress_timeout` without motion — and a robot that is early at a windowed task
stands still until its window opens, then for the task's service. On Solomon's C1 sets (windows
opening up to 300 s in, 25 s services, a 10 s timeout) every robot declared every other one
stalled: each became its own auctioneer, awarded itself everything, and the real auctioneer
refused the served reports that followed as forged (`not_held`: TeSSI on C103, w23's run 93).

A team on the in-process exchange and a manual clock (tests/harness/route_team.py), whose
bodies wait for the window as the delivery layer does."""

from __future__ import annotations

import pytest

from mrta_agent.cbba.agent import CbbaCoordinator
from mrta_agent.cbba.architecture import CBBA
from mrta_agent.cbba.params import CbbaKeys
from mrta_agent.ssi.agent import SsiCoordinator
from mrta_agent.ssi.architecture import SSI
from mrta_agent.ssi.params import SsiKeys
from mrta_agent.tessi.agent import TessiCoordinator
from mrta_agent.tessi.architecture import TESSI
from mrta_agent.tessi.params import TessiKeys
from mrta_zenoh.planning import Problem, Robot, Task
from tests.harness.route_team import RouteTeam, params_for

TIMEOUT = 5.0
# each robot is 2 s from its task, whose window opens 20 s (25 s) in: 18 s (23 s) of waiting,
# then 8 s of service — both longer than the timeout
EARLY = Problem((Robot("robot1", (0.0, 0.0), 1.0), Robot("robot2", (10.0, 0.0), 1.0)),
                (Task("t1", (2.0, 0.0), service=8.0, earliest=20.0),
                 Task("t2", (8.0, 0.0), service=8.0, earliest=25.0)))
MAKE = {
    "ssi": (SSI, lambda p, rid, body: SsiCoordinator(rid, params_for(p, SsiKeys(), TIMEOUT),
                                                     body)),
    "tessi": (TESSI, lambda p, rid, body: TessiCoordinator(
        rid, params_for(p, TessiKeys(), TIMEOUT), body)),
    "cbba": (CBBA, lambda p, rid, body: CbbaCoordinator(rid, params_for(p, CbbaKeys(), TIMEOUT),
                                                       body)),
}


@pytest.mark.parametrize("arch", sorted(MAKE))
def test_a_robot_waiting_for_its_window_and_serving_is_not_counted_stalled(arch):
    contract, make = MAKE[arch]
    t = RouteTeam(EARLY, contract.messages, lambda rid, body: make(EARLY, rid, body))
    ever: set[tuple[str, str]] = set()
    while t.now < 40.0:
        t.step()
        ever |= {(rid, other) for rid, c in t.coords.items() for other in c.declared}
    assert ever == set()  # nobody counted anyone out
    assert t.served() == {"robot1": ["t1"], "robot2": ["t2"]}
    assert all(sum(c.refusals().values()) == 0 for c in t.coords.values())
    for rid, c in t.coords.items():
        for s in c.route.served:  # served after its window opened and its service ran
            task = EARLY.tasks[EARLY.task_index(s.task)]
            assert s.at >= task.earliest + task.service - 1e-9


def test_a_robot_that_stands_still_after_its_window_opened_is_still_counted_stalled():
    """The watch waits for the window and the service, not for ever: robot2 stalls at its task
    before its window opens and is counted out `progress_timeout` after its service would
    have ended."""
    contract, make = MAKE["ssi"]
    t = RouteTeam(EARLY, contract.messages, lambda rid, body: make(EARLY, rid, body))
    t.run_until(6.0)
    t.stall("robot2")
    t2 = EARLY.tasks[1]
    t.run_until(t2.earliest + t2.service + TIMEOUT - 1.0)
    assert "robot2" not in t.coords["robot1"].declared
    t.run_until(t2.earliest + t2.service + TIMEOUT + 2.0)
    assert t.coords["robot1"].declared.get("robot2") == "stalled"


# three robots, five windowed tasks, waits of up to 40 s: before the watch waited for windows,
# TeSSI's auctioneer refused 4 of robot2's served reports as forged (`not_held`, as on C103)
# and t3 was served three times
SPLIT = Problem((Robot("robot1", (3.24, 1.51), 1.0), Robot("robot2", (6.51, 0.72), 1.0),
                 Robot("robot3", (5.36, 3.66), 1.0)),
                (Task("t1", (5.07, 0.37), service=6.9, earliest=12.9, due=25.0),
                 Task("t2", (4.25, 8.27), service=4.1, earliest=14.5, due=31.2),
                 Task("t3", (9.48, 5.77), service=6.6, earliest=41.4, due=80.7),
                 Task("t4", (8.58, 2.9), service=4.3, earliest=12.3, due=25.9),
                 Task("t5", (8.16, 1.81), service=8.2, earliest=25.4, due=54.6)))


def test_tessi_serves_each_task_once_and_refuses_nothing_across_long_window_waits():
    contract, make = MAKE["tessi"]
    t = RouteTeam(SPLIT, contract.messages, lambda rid, body: make(SPLIT, rid, body))
    t.run_until(100.0)
    served = [task for tasks in t.served().values() for task in tasks]
    assert sorted(served) == ["t1", "t2", "t3", "t4", "t5"], t.served()
    assert {rid: dict(c.refusals()) for rid, c in t.coords.items()} == \
        {rid: {} for rid in t.coords}
    assert not any(c.declared for c in t.coords.values())


def test_centrals_dispatcher_waits_for_the_window_and_the_service_of_a_robot_at_its_task():
    """Central's watch rules alike (robot_agent/central/dispatcher.py, `_stalled`): robot1 at
    its task from 0.1 s, the window opening at 30 s, 8 s of service — it is stalled only
    `progress_timeout` after that (it was at 13.1 s, the window ignored)."""
    from mrta_agent.central.dispatcher import Dispatcher
    from mrta_agent.central.params import DispatcherParams
    from mrta_agent.route.messages import Progress
    from mrta_zenoh.messages import Header
    p = Problem((Robot("robot1", (0.0, 0.0), 1.0),),
                (Task("t1", (1.0, 0.0), service=8.0, earliest=30.0),))
    d = Dispatcher(p, DispatcherParams(progress_timeout=5.0))
    d.teammate("robot1", True)
    d.tick(0.0)
    version, now = d.sent["robot1"].version, 0.1
    while d.robots["robot1"].lost is None and now < 60.0:
        d.hear("progress", "robot1",
               Progress(Header("", 0.0, 0), "t1", "", ("t1",), (), 1.0, 0.0, 0.0, version), now)
        d.tick(now)
        now = round(now + 0.1, 1)
    assert d.robots["robot1"].lost == "stalled"
    assert 30.0 + 8.0 + 5.0 <= now <= 30.0 + 8.0 + 5.0 + 0.3


def test_a_teammate_pushed_off_its_task_while_serving_is_still_at_it():
    """Within 1 m of its task a teammate is at it (AT_TASK): a serving robot pushed 0.64 m off
    its task (Solomon C102, CBBA) was declared stalled at 0.5 m; 2 m off it is travelling."""
    from mrta_agent.route.messages import Progress
    from mrta_agent.route.own_route import Watch
    from mrta_zenoh.messages import Header
    contract, make = MAKE["ssi"]
    t = RouteTeam(EARLY, contract.messages, lambda rid, body: make(EARLY, rid, body))
    due = {}
    for off in (0.8, 2.0):
        w = Watch()
        w.heard(Progress(Header("robot2", 3.0, 1), "t2", "", ("t2",), (), 8.0, off, 0.0), 3.0)
        due[off] = t.coords["robot1"]._progress_due(w)
    assert due == {0.8: 25.0 + 8.0 + TIMEOUT, 2.0: 3.0 + TIMEOUT}
