"""central under a real network cut (issue 51): the cut ends the cut-off robot's session, so the
dispatcher sees its token go (a crash, it re-grants its tasks at once) and the robot sees its
dispatcher's token go — with its teammates'. The robot must then hold, not finish its queue as
after a dispatcher crash (robot_agent/central/agent.py, Lease); the dispatcher counts a
returning robot's silence from its return. The robot logic and the dispatcher alone, on
explicit times (tests/process/test_central_tcp_cut.py runs the real cut)."""

from __future__ import annotations

from mrta_agent.central.agent import CentralCoordinator
from mrta_agent.central.architecture import DISPATCHER
from mrta_agent.central.dispatcher import Dispatcher
from mrta_agent.central.messages import Progress, Queue
from mrta_agent.central.params import DispatcherParams
from mrta_zenoh.messages import Header
from mrta_zenoh.planning import Problem, Robot, Task
from tests.harness.central_team import Body, robot_params

FAR = Problem((Robot("robot1", (0.0, 0.0), 0.5), Robot("robot2", (10.0, 0.0), 0.5)),
              (Task("t1", (9.0, 0.0), service=1.0),))


def robot(teammates=("robot2",)) -> CentralCoordinator:
    """robot1 on its way to t1 (its queue v1), its dispatcher's and `teammates`' tokens seen."""
    c = CentralCoordinator("robot1", robot_params(lease=3.0), dispatcher=DISPATCHER,
                           readings=Body(0.0, 0.0, 0.5, FAR))
    for who in (DISPATCHER, *teammates):
        c.teammate(who, True)
    c.hear("queue", DISPATCHER, Queue(Header(DISPATCHER, 0.0, 1), "robot1", 1, ("t1",)), 0.0)
    c.tick(0.0)
    assert c.active_task == "t1" and not c.holding
    return c


def test_a_robot_cut_off_from_its_dispatcher_and_teammates_holds_until_it_hears_a_queue():
    c = robot()
    c.teammate(DISPATCHER, False)
    c.teammate("robot2", False)
    c.tick(1.0)
    assert c.holding and c.active_task is None and c.route.queue == ["t1"]
    c.tick(30.0)
    assert c.holding  # for as long as the cut lasts
    c.teammate(DISPATCHER, True)
    c.teammate("robot2", True)
    c.tick(30.1)
    assert c.holding and c.active_task is None  # back, but silent beyond its lease
    c.hear("queue", DISPATCHER, Queue(Header(DISPATCHER, 30.1, 2), "robot1", 2, ()), 30.2)
    c.tick(30.2)
    assert not c.holding and c.route.queue == []  # t1 went to robot2 meanwhile: left


def test_teammates_lost_within_the_lease_of_the_dispatcher_mark_a_cut():
    c = robot(("robot2", "robot3"))
    c.teammate(DISPATCHER, False)
    c.tick(1.0)
    assert c.active_task == "t1"  # so far, the dispatcher's crash
    c.teammate("robot2", False)   # robot3 is on this side of the cut
    c.tick(2.5)
    assert c.holding and c.active_task is None


def test_a_dispatcher_crash_alone_leaves_the_robot_finishing_its_queue():
    c = robot(("robot2", "robot3"))
    c.teammate(DISPATCHER, False)
    c.tick(1.0)
    c.teammate("robot2", False)  # a teammate's crash long after is no cut
    c.tick(10.0)
    assert not c.holding and c.active_task == "t1"


def test_a_robot_that_never_had_a_teammate_finishes_its_queue_when_its_dispatcher_goes():
    c = robot(())
    c.teammate(DISPATCHER, False)
    c.tick(1.0)
    assert not c.holding and c.active_task == "t1"


def test_a_robot_back_from_a_cut_is_not_declared_silent_for_its_time_away():
    d = Dispatcher(FAR, DispatcherParams(progress_timeout=5.0))
    for r in FAR.robots:
        d.teammate(r.id, True)
    list(d.tick(0.0))
    assert d.hear("progress", "robot1", Progress(Header("robot1", 0.5, 1), "", "", (), (), 0.0,
                                                 0.0, 0.0, 1), 0.5)
    d.teammate("robot1", False)  # its session ended: a crash, as far as anyone can tell
    list(d.tick(1.0))
    assert d.robots["robot1"].lost == "crashed"
    d.teammate("robot1", True)
    list(d.tick(30.0))
    list(d.tick(34.0))
    assert d.robots["robot1"].lost is None  # silent only progress_timeout after its return
    list(d.tick(35.1))
    assert d.robots["robot1"].lost == "silent"
