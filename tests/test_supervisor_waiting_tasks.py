"""A task nobody holds while every robot able to serve it is busy waits for a robot to be free
(supervisor/live/tasks.py, waits_for_a_robot): under MURDOCH, which keeps no queue, a time-extended
delivery (more tasks than robots) runs that way, and the supervisor raises no
`task_unattended` for it. A capable robot idle beside it, or none online, is still an alarm."""

from __future__ import annotations

import pytest

from mrta_agent.murdoch.messages import Claim
from mrta_delivery.instance import InstanceBody, RobotSpec, TaskSpec
from mrta_delivery.messages import TaskEvent
from mrta_delivery.mission import DeliveryWatch
from mrta_supervisor.live.api import resolve_application
from mrta_supervisor.live.state import Supervisor
from mrta_supervisor.live.tasks import waits_for_a_robot
from mrta_zenoh.messages import Header

ROBOTS = ("robot1", "robot2", "robot3", "robot4", "robot5")
UNATTENDED = 30.0


def delivery_params() -> InstanceBody:
    """t3 needs `cold`, which only robot1 and robot2 have."""
    robots = {r: RobotSpec(start=(float(k), 0.0), speed=0.5,
                           capabilities=("cold",) if r in ("robot1", "robot2") else ())
              for k, r in enumerate(ROBOTS)}
    tasks = {t: TaskSpec(position=(1.0, 1.0), capability="cold" if t == "t3" else "")
             for t in ("t1", "t2", "t3", "t4")}
    return InstanceBody(robots=robots, tasks=tasks)


@pytest.fixture
def sup():
    app, arch = resolve_application("delivery_murdoch")
    assert sorted(r.id for r in app.robots) == list(ROBOTS)
    s = Supervisor(arch, app, 0.0, unattended_after=UNATTENDED, quiet=True,
                   watch=DeliveryWatch(delivery_params()))
    for r in ROBOTS:
        s.on_liveliness(f"{r}/murdoch/agent", True, 0.0)
    return s


def claim(s: Supervisor, robot: str, task: str, now: float) -> None:
    s.on_sample(s.monitors, f"{robot}/murdoch/claim", "murdoch_msgs/Claim",
                Claim(Header(robot, now, int(now * 10)), task, 0.0, 2.0), now)


def unattended(s: Supervisor, now: float) -> set[str]:
    return {a["subject"] for a in s.snapshot(now)["alarms"] if a["kind"] == "task_unattended"}


def run(s: Supervisor, start: float, end: float, holders: dict[str, str]) -> float:
    """Robots in `holders` claim their task every 0.5 s from `start` to `end`."""
    now = start
    while now < end:
        for robot, task in holders.items():
            claim(s, robot, task, now)
        s.update(now)
        now = round(now + 0.5, 6)
    return now


def test_a_task_waiting_for_its_only_capable_robots_to_be_free_is_not_unattended(sup):
    # robot1 and robot2 (the only ones with `cold`) are on t1, t2 for 70 s; robot4 on t4;
    # robot3 and robot5 idle, but they cannot serve t3
    now = run(sup, 0.0, 70.0, {"robot1": "t1", "robot2": "t2", "robot4": "t4"})
    tasks = {t["id"]: t for t in sup.snapshot(now)["tasks"]}
    assert tasks["t3"]["state"] == "unallocated" and tasks["t3"]["robots"] == []
    assert "t3" not in unattended(sup, now)
    # robot2 delivers t2 and is idle, but leaves t3 alone: unattended 30 s later
    for event, at in (("started", now - 5.0), ("done", now)):
        sup.on_task_sample(f"robot2/delivery/{event}",
                           TaskEvent(Header("robot2", at, 99), "t2", event), now)
    now = run(sup, now, now + UNATTENDED - 5.0, {"robot1": "t1", "robot4": "t4"})
    assert "t3" not in unattended(sup, now)
    now = run(sup, now, now + 10.0, {"robot1": "t1", "robot4": "t4"})
    assert "t3" in unattended(sup, now)


def test_a_task_no_online_robot_can_serve_is_unattended(sup):
    sup.on_liveliness("robot1/murdoch/agent", False, 1.0)
    sup.on_liveliness("robot2/murdoch/agent", False, 1.0)
    now = run(sup, 1.0, 1.0 + UNATTENDED + 1.0, {"robot4": "t4"})
    assert "t3" in unattended(sup, now)


def test_waits_for_a_robot_from_its_definition():
    busy, idle, off = "busy", "idle", "offline"
    cold = frozenset({"robot1", "robot2"})
    assert waits_for_a_robot(cold, {"robot1": busy, "robot2": busy, "robot3": idle})
    assert waits_for_a_robot(cold, {"robot1": busy, "robot2": off, "robot3": idle})
    assert not waits_for_a_robot(cold, {"robot1": busy, "robot2": idle})
    assert not waits_for_a_robot(cold, {"robot1": off, "robot2": off, "robot3": busy})
    assert not waits_for_a_robot(None, {"robot1": busy, "robot3": idle})
    assert waits_for_a_robot(None, {"robot1": busy, "robot3": busy})


def test_a_continuous_task_left_alone_while_the_others_are_busy_is_unattended():
    """Patrol's tasks never end, so no robot becomes free of one: its watch does not serve
    tasks in turn, and wander, left by robot2 when it went offline, is unattended although
    every online robot is busy."""
    from mrta_supervisor.mission.hook import application_watch
    app, arch = resolve_application("patrol_murdoch")
    watch = application_watch(app)
    assert watch is not None and not watch.served_in_turn
    s = Supervisor(arch, app, 0.0, unattended_after=UNATTENDED, quiet=True, watch=watch)
    for r in ("robot1", "robot2", "robot3"):
        s.on_liveliness(f"{r}/murdoch/agent", True, 0.0)
    s.on_liveliness("robot2/murdoch/agent", False, 1.0)
    now = run(s, 1.0, 1.0 + UNATTENDED + 2.0, {"robot1": "border_protection",
                                               "robot3": "report"})
    assert {r["id"]: r["state"] for r in s.snapshot(now)["robots"]}["robot1"] == "busy"
    assert "wander" in unattended(s, now)
