"""The supervisor across a run's life, on a manual clock: tasks the application says are done
or not due yet, the end of a run, a restarted simulator."""

from __future__ import annotations

import pytest

from mrta_agent.alliance.messages import InterRobotCommunication
from mrta_zenoh.clock import SimClock
from mrta_zenoh.messages import Header
from mrta_supervisor.live.api import CLOCK_STALL, Elapsed, Refresh, resolve_application
from mrta_supervisor.live.state import Supervisor
from mrta_supervisor.live.tasks import TaskStatus, TaskWatch
from mrta_supervisor.live.view import render
from mrta_supervisor.mission.hook import application_watch

IRC = "alliance_msgs/InterRobotCommunication"


class FakeWall:
    def __init__(self):
        self.t = 0.0

    def __call__(self):
        return self.t


def irc(sup, robot, task, now):
    sup.on_sample(sup.monitors, f"{robot}/alliance/inter_robot_communication", IRC,
                  InterRobotCommunication(Header(robot, now, 0), task, 60.0), now)


def tasks_of(sup, now):
    return {t["id"]: t["state"] for t in sup.snapshot(now)["tasks"]}


def alarms_of(sup, now):
    return {(a["kind"], a["subject"]) for a in sup.snapshot(now)["alarms"]}


def run(sup, t0, t1, step=0.25, *busy):
    """Refresh from t0 to t1; the (robot, task) pairs in `busy` broadcast meanwhile."""
    t = t0
    while t <= t1 + 1e-9:
        for robot, task in busy:
            irc(sup, robot, task, t)
        sup.update(t)
        t += step


@pytest.fixture
def patrol():
    return resolve_application("patrol")


class Scripted(TaskWatch):
    """A watch whose news the test hands in."""

    def __init__(self, schedule=()):
        self._schedule = list(schedule)

    def schedule(self):
        return self._schedule

    def read(self, key, message):
        return message  # the test's "message" is the status itself


def test_a_task_done_or_not_due_yet_is_shown_so_and_raises_no_alarm(patrol):
    app, arch = patrol
    watch = Scripted([TaskStatus("border_protection", "waiting", 100.0)])
    sup = Supervisor(arch, app, 0.0, unattended_after=30.0, watch=watch)
    for rid in ("robot1", "robot2", "robot3"):
        sup.on_liveliness(f"{rid}/alliance/agent", True, 0.0)
    assert tasks_of(sup, 0.0)["border_protection"] == "waiting"
    run(sup, 0.0, 12.0, 0.25, ("robot3", "report"))
    sup.on_task_sample("robot3/patrol/report", TaskStatus("report", "done", 60.0), 12.0)
    run(sup, 12.25, 71.0)   # the report's broadcasts have stopped: its holder falls at 14.5
    snap = tasks_of(sup, 71.0)
    assert snap["report"] == "done" and snap["border_protection"] == "waiting"
    # wander has had no robot since 0: that one is alarmed; done and waiting ones are not
    assert alarms_of(sup, 71.0) == {("task_unattended", "wander")}
    # due again at 72 (12 + 60): unallocated from then, alarmed 30 s later
    run(sup, 71.25, 101.75)
    assert tasks_of(sup, 101.75)["report"] == "unallocated"
    assert ("task_unattended", "report") not in alarms_of(sup, 101.75)
    run(sup, 102.0, 102.0)
    assert ("task_unattended", "report") in alarms_of(sup, 102.0)
    # border_protection arrived at 100: unattended only from 130
    assert ("task_unattended", "border_protection") not in alarms_of(sup, 102.0)
    run(sup, 102.25, 130.0)
    assert ("task_unattended", "border_protection") in alarms_of(sup, 130.0)


def test_a_robot_on_a_task_shows_it_allocated_whatever_the_application_says(patrol):
    app, arch = patrol
    sup = Supervisor(arch, app, 0.0, watch=Scripted())
    sup.on_liveliness("robot1/alliance/agent", True, 0.0)
    irc(sup, "robot1", "wander", 1.0)
    sup.on_task_sample("robot1/x", TaskStatus("wander", "done"), 1.0)
    assert tasks_of(sup, 1.0)["wander"] == "allocated"
    sup.update(4.0)  # its broadcasts stopped: now the application's word shows
    assert tasks_of(sup, 4.0)["wander"] == "done"
    sup.on_task_sample("robot1/x", TaskStatus("dance", "done"), 4.0)  # not a task of the app
    assert sup.counts["task_news_ignored"] == 1 and "dance" not in tasks_of(sup, 4.0)


def test_patrols_watch_says_a_report_is_done_for_its_period():
    from mrta_patrol.messages import Report

    app, arch = resolve_application("patrol")
    watch = application_watch(app)
    assert watch is not None and watch.feed()[0][0] == "*/patrol/report"
    msg = Report(Header("robot3", 12.3, 1), 120.0, 0.3, ())
    # done for Report/period (the package's layers file: 60 s)
    assert watch.read("robot3/patrol/report", msg) == TaskStatus("report", "done", 60.0)
    assert watch.read("robot1/patrol/report", msg) is None  # robot1's key, robot3's header


def test_deliverys_watch_says_delivered_tasks_are_done_and_late_ones_waiting():
    from mrta_delivery.instance import InstanceBody, RobotSpec, TaskSpec
    from mrta_delivery.messages import TaskEvent
    from mrta_delivery.mission import DeliveryWatch

    watch = DeliveryWatch(InstanceBody(robots={"robot2": RobotSpec(start=(-4.0, 0.0), speed=1.0)},
                                       tasks={"t1": TaskSpec(position=(0.0, 0.0), service=2.0),
                                              "t2": TaskSpec(position=(1.0, 0.0),
                                                             arrival=40.0)}))
    assert watch.schedule() == [TaskStatus("t2", "waiting", 40.0)]
    done = TaskEvent(Header("robot2", 9.0, 3), "t1", "done")
    # a done before its sender said it started serving: not believed (a forger's, issue 51)
    assert watch.read("robot2/delivery/done", done) is None
    started = TaskEvent(Header("robot2", 5.0, 2), "t1", "started")
    assert watch.read("robot2/delivery/started", started) == TaskStatus("t1", "done")
    assert watch.read("robot2/delivery/done", done) == TaskStatus("t1", "done")
    assert watch.read("robot1/delivery/done", done) is None
    # and the shipped application finds it through its mission hook
    app, _ = resolve_application("delivery")
    assert isinstance(application_watch(app), DeliveryWatch)


def test_the_end_of_a_run_raises_no_clock_stopped(patrol):
    """The simulator exits at its duration (it announces the end, then its clock source token
    goes first): no alarm, robots keep the state the run left them in, the snapshot says the
    run ended. A simulator killed (its token gone unannounced) or hung is a stopped clock."""
    app, arch = patrol
    wall = FakeWall()
    clock = SimClock(wall=wall)
    clock.on_source("run-a-x2", True)
    clock.on_clock(60.0, "run-a-x2")
    sup = Supervisor(arch, app, 60.0)
    refresh = Refresh(sup, clock, sim_time=True)
    sup.on_liveliness("robot1/alliance/agent", True, 60.0)
    irc(sup, "robot1", "wander", 60.0)
    clock.on_source("run-a-x2/ended", True)  # it ends on purpose
    clock.on_source("run-a-x2", False)  # the simulator's token is gone
    assert clock.ended()
    wall.t = 10 * CLOCK_STALL
    refresh()
    snap = sup.snapshot(60.0)
    assert snap["alarms"] == [] and snap["run_ended"] is True
    assert snap["robots"][0]["state"] == "busy"
    # the run's processes then stop: no communication_lost — it is over — and the picture
    # stays as the run left it (issue 51: at a replay's end every robot turned offline)
    sup.on_liveliness("robot1/alliance/agent", False, 60.0)
    sup.on_process_token("@mrta/node/simulator", False, 60.0)
    refresh()
    snap = sup.snapshot(60.0)
    assert snap["robots"][0]["state"] == "busy" and snap["alarms"] == []
    assert snap["robots"][0]["task"] == "wander"
    assert "the run ended at 60.0 s" in " ".join(
        str(p) for p in render(snap).renderables if hasattr(p, "plain"))
    # a simulator that hangs (its token alive) is a stopped clock, alarmed
    clock2 = SimClock(wall=wall)
    clock2.on_source("run-b-x2", True)
    clock2.on_clock(30.0, "run-b-x2")
    sup2 = Supervisor(arch, app, 30.0)
    wall.t += 10 * CLOCK_STALL
    Refresh(sup2, clock2, sim_time=True)()
    assert not clock2.ended() and ("clock_stopped", "clock") in alarms_of(sup2, 30.0)
    # a simulator killed: its token goes with no end announced — alarmed, robots unknown
    clock3 = SimClock(wall=wall)
    clock3.on_source("run-c-x2", True)
    clock3.on_clock(30.0, "run-c-x2")
    sup3 = Supervisor(arch, app, 30.0)
    sup3.on_liveliness("robot1/alliance/agent", True, 30.0)
    clock3.on_source("run-c-x2/ended", False)  # an end token of another kind counts for nothing
    clock3.on_source("run-c-x2", False)
    wall.t += 10 * CLOCK_STALL
    Refresh(sup3, clock3, sim_time=True)()
    snap = sup3.snapshot(30.0)
    assert not clock3.ended() and not snap["run_ended"]
    assert ("clock_stopped", "clock") in alarms_of(sup3, 30.0)
    assert snap["robots"][0]["state"] == "unknown"


def test_a_restarted_simulator_starts_the_picture_afresh(patrol):
    """The old run's robot2 crash must not live on in the new run: no `-261s`, no alarm
    `since 287.8`; the picture is what a supervisor started at the restart would show."""
    app, arch = patrol
    sup = Supervisor(arch, app, 0.0)
    for rid in ("robot1", "robot2", "robot3"):
        sup.on_liveliness(f"{rid}/alliance/agent", True, 0.0)
    run(sup, 0.0, 280.0, 0.5, ("robot1", "wander"), ("robot2", "border_protection"))
    sup.on_liveliness("robot2/alliance/agent", False, 287.8)
    run(sup, 288.0, 300.0, 0.5, ("robot1", "wander"))
    assert ("communication_lost", "robot2") in alarms_of(sup, 300.0)
    sup.restart(0.4)  # the new run's first clock
    snap = sup.snapshot(0.4)
    fresh = Supervisor(arch, app, 0.4)
    for rid in ("robot1", "robot3"):
        fresh.on_liveliness(f"{rid}/alliance/agent", True, 0.4)
    want = fresh.snapshot(0.4)
    assert snap["robots"] == want["robots"] and snap["tasks"] == want["tasks"]
    assert snap["alarms"] == want["alarms"] == []
    assert all(r["since"] <= 0.4 for r in snap["robots"])
    assert [(t["kind"], t["to"]) for t in snap["transitions"]][0] == ("run", "restarted")
    assert all(t["time"] <= 0.4 for t in snap["transitions"])
    # and the new run goes on as a fresh one would: robot2's agent back, busy again
    sup.on_liveliness("robot2/alliance/agent", True, 1.0)
    irc(sup, "robot2", "border_protection", 1.0)
    assert sup.snapshot(1.0)["robots"][1]["state"] == "busy"


def test_a_new_run_seen_through_refresh_restarts_the_picture(patrol):
    app, arch = patrol
    wall = FakeWall()
    clock = SimClock(wall=wall)
    clock.on_clock(287.0, "run-a")
    sup = Supervisor(arch, app, clock.now())
    refresh = Refresh(sup, clock, sim_time=True)
    sup.on_liveliness("robot2/alliance/agent", True, 287.0)
    sup.on_liveliness("robot2/alliance/agent", False, 287.8)
    assert ("communication_lost", "robot2") in alarms_of(sup, 287.8)
    wall.t = 3.0
    clock.on_clock(0.5, "run-b")
    assert refresh() == 0.5
    robot2 = sup.snapshot(0.5)["robots"][1]
    assert robot2["state"] == "offline" and robot2["since"] == 0.5
    assert alarms_of(sup, 0.5) == set()


def test_elapsed_counts_across_a_new_run():
    e = Elapsed(100.0)
    assert e(130.0) == 30.0
    assert e(0.5) == 30.0  # time restarted: nothing counted backwards
    assert e(10.5) == 40.0


def test_robots_going_right_after_the_clock_source_raise_no_alarm(patrol):
    """A replay (or a launch) ends: the clock source's token goes, then at once the robots'
    — before the next refresh. The supervisor sees the run's end with the first of them."""
    app, arch = patrol
    clock = SimClock(wall=FakeWall())
    clock.on_source("run-a-x4", True)
    clock.on_clock(40.0, "run-a-x4")
    sup = Supervisor(arch, app, 40.0)
    Refresh(sup, clock, sim_time=True)()
    sup.on_liveliness("robot1/alliance/agent", True, 40.0)
    clock.on_source("run-a-x4/ended", True)
    clock.on_source("run-a-x4", False)
    sup.on_liveliness("robot1/alliance/agent", False, 40.0)  # no refresh in between
    snap = sup.snapshot(40.0)
    assert snap["run_ended"] and snap["alarms"] == []
    assert snap["robots"][0]["state"] == "idle"  # as the run left it, not offline
