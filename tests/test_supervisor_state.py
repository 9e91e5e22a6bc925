"""Supervisor logic on a manual clock: holders, robot and task states, alarms, bad samples."""

import json
import textwrap

import pytest

from mrta_zenoh.bus.inproc import InProcBus, InProcNetwork
from mrta_zenoh.clock import ManualClock, SimClock
from mrta_zenoh.messages import GenericMessage, Header, Twist
from mrta_agent.alliance.messages import InterRobotCommunication
from tests.harness.helpers import ALLIANCE_ARCH
from mrta_zenoh.toolchain.model import ApplicationFile, RobotEntry
from mrta_zenoh.toolchain.xmlio import load_rqt_mrta
from mrta_supervisor.live.api import CLOCK_STALL, Refresh, attach, resolve_application
from mrta_supervisor.live.holders import SampleHolder
from mrta_supervisor.live.state import Supervisor
from mrta_supervisor.live.tasks import TaskStatus, TaskWatch
from mrta_zenoh.toolchain.model import Topic

IRC = "alliance_msgs/InterRobotCommunication"


def test_sample_holder_edges():
    h = SampleHolder(2.0)
    assert h.sample(0.0) is True and h.sample(1.0) is False
    assert h.update(2.9) is False and h.high
    assert h.update(3.0) is True and not h.high
    assert h.update(4.0) is False
    assert h.sample(5.0) is True
    with pytest.raises(ValueError):
        SampleHolder(0)


@pytest.fixture
def patrol():
    app, arch = resolve_application("patrol")
    return app, arch


def irc(sup, monitors, robot, task, now):
    sup.on_sample(monitors, f"{robot}/alliance/inter_robot_communication", IRC,
                  InterRobotCommunication(Header(robot, now, 0), task, 60.0), now)


def state(sup, now):
    snap = sup.snapshot(now)
    return ({r["id"]: (r["state"], r["task"]) for r in snap["robots"]},
            {t["id"]: (t["state"], t["robots"]) for t in snap["tasks"]},
            {(a["kind"], a["subject"]) for a in snap["alarms"]})


def test_busy_idle_offline_and_tasks_from_the_alliance_architecture(patrol):
    app, arch = patrol
    sup = Supervisor(arch, app, 0.0, unattended_after=10.0, duplicate_after=3.0)
    mons = sup.monitors
    robots, tasks, alarms = state(sup, 0.0)
    assert robots == {r: ("offline", None) for r in ("robot1", "robot2", "robot3")}
    sup.on_liveliness("robot1/alliance/agent", True, 0.5)
    sup.on_liveliness("robot2/alliance/agent", True, 0.5)
    irc(sup, mons, "robot1", "wander", 1.0)
    robots, tasks, _ = state(sup, 1.0)
    assert robots["robot1"] == ("busy", "wander") and robots["robot2"] == ("idle", None)
    assert robots["robot3"] == ("offline", None)
    assert tasks["wander"] == ("allocated", ["robot1"]) and tasks["report"][0] == "unallocated"
    sup.update(3.4)  # within the 2.5 s timeout of the sample at 1.0
    assert state(sup, 3.4)[0]["robot1"][0] == "busy"
    sup.update(3.6)
    robots, tasks, alarms = state(sup, 3.6)
    assert robots["robot1"] == ("idle", None) and tasks["wander"] == ("unallocated", [])
    # tasks nobody took for 10 s raise an alarm; allocation clears it
    sup.update(10.5)
    assert ("task_unattended", "border_protection") in state(sup, 10.5)[2]
    irc(sup, mons, "robot2", "border_protection", 11.0)
    assert ("task_unattended", "border_protection") not in state(sup, 11.0)[2]
    # two robots on a single-robot task for 3 s → alarm
    for t in (12.0, 13.0, 14.0, 15.0):
        irc(sup, mons, "robot1", "border_protection", t)
        irc(sup, mons, "robot2", "border_protection", t)
        sup.update(t)
    assert ("task_duplicated", "border_protection") in state(sup, 15.0)[2]
    # token lost → offline at once, its allocation dropped, alarm raised
    sup.on_liveliness("robot2/alliance/agent", False, 15.2)
    robots, tasks, alarms = state(sup, 15.2)
    assert robots["robot2"] == ("offline", None)
    assert tasks["border_protection"] == ("allocated", ["robot1"])
    assert ("communication_lost", "robot2") in alarms
    assert ("task_duplicated", "border_protection") not in alarms
    sup.on_liveliness("robot2/alliance/agent", True, 16.0)
    assert ("communication_lost", "robot2") not in state(sup, 16.0)[2]
    kinds = [(t.kind, t.subject, t.new) for t in sup.history.all()]
    assert ("robot", "robot2", "offline") in kinds and ("alarm", "task_duplicated:border_protection",
                                                       "raised") in kinds


def test_unknown_robots_wrong_types_and_bad_fields_do_not_disturb_state(patrol):
    app, arch = patrol
    sup = Supervisor(arch, app, 0.0)
    mons = sup.monitors
    sup.on_liveliness("robot1/alliance/agent", True, 0.0)
    irc(sup, mons, "robot1", "wander", 1.0)
    before = state(sup, 1.0)
    sup.on_sample(mons, "robot1/alliance/inter_robot_communication", "mrta_msgs/Twist",
                  Twist(1.0, 0.0), 1.1)
    sup.on_sample(mons, "robot1/alliance/inter_robot_communication", IRC,
                  GenericMessage(IRC, {"task_id": "wander"}), 1.2)  # no header: bad field
    sup.on_sample(mons, "robot1/alliance/inter_robot_communication", IRC,
                  InterRobotCommunication(Header("not a robot id!", 1.3, 0), "x", 1.0), 1.3)
    assert state(sup, 1.3) == before
    assert sup.counts["wrong_type"] == 1 and sup.counts["field_errors"] == 2
    irc(sup, mons, "robot9", "wander", 2.0)  # not in the application: an alarm, not a robot
    robots, tasks, alarms = state(sup, 2.0)
    assert "robot9" not in robots
    assert tasks["wander"] == ("allocated", ["robot1"])
    assert ("unknown_robot", "robot9") in alarms
    sup.update(2.0 + sup.unknown_expiry)  # forgotten once it stops
    assert ("unknown_robot", "robot9") not in state(sup, 40.0)[2]


def test_a_sample_on_one_robots_key_cannot_speak_for_another(patrol):
    app, arch = patrol
    sup = Supervisor(arch, app, 0.0)
    sup.on_liveliness("robot2/alliance/agent", True, 0.0)
    sup.on_sample(sup.monitors, "robot1/alliance/inter_robot_communication", IRC,
                  InterRobotCommunication(Header("robot2", 1.0, 0), "border_protection", 60.0), 1.0)
    robots, tasks, _ = state(sup, 1.0)
    assert robots["robot2"] == ("idle", None) and tasks["border_protection"][1] == []
    assert sup.counts["key_mismatch"] == 1


def test_unknown_tasks_raise_an_alarm_and_stay_out(patrol):
    app, arch = patrol
    sup = Supervisor(arch, app, 0.0)
    sup.on_liveliness("robot1/alliance/agent", True, 0.0)
    irc(sup, sup.monitors, "robot1", "dance", 1.0)
    robots, tasks, alarms = state(sup, 1.0)
    assert "dance" not in tasks and ("unknown_task", "dance") in alarms


def test_tasks_submitted_at_run_time_join_the_picture_from_the_intakes_changes(patrol):
    """A task that entered through the intake (`tasks/change`, issue 50) is shown and held
    like the application's own, with no `unknown_task` — also when a robot named it before its
    change came; a change not from the intake grows nothing; a cancelled task is `cancelled`,
    unattended by no alarm; a new run forgets them."""
    from mrta_zenoh.tasks.messages import Change

    app, arch = patrol
    sup = Supervisor(arch, app, 0.0, unattended_after=5.0)
    sup.on_liveliness("robot1/alliance/agent", True, 0.0)
    irc(sup, sup.monitors, "robot1", "n1", 1.0)  # heard before its change
    assert ("unknown_task", "n1") in state(sup, 1.0)[2]
    sup.on_change(Change(Header("tasks", 0.9, 1), "submit", "n1", "{}"), 1.1)
    sup.on_change(Change(Header("tasks", 0.9, 2), "submit", "n2", "{}"), 1.1)
    sup.on_change(Change(Header("robot1", 0.9, 1), "submit", "f1", "{}"), 1.1)  # forged
    irc(sup, sup.monitors, "robot1", "n1", 1.2)
    sup.update(1.2)
    robots, tasks, alarms = state(sup, 1.2)
    assert tasks["n1"] == ("allocated", ["robot1"]) and robots["robot1"] == ("busy", "n1")
    assert "f1" not in tasks and not {a for a in alarms if a[0] == "unknown_task"}
    assert sup.counts["task_changes"] == 2 and sup.counts["task_changes_ignored"] == 1
    sup.on_change(Change(Header("tasks", 2.0, 3), "cancel", "n2"), 2.0)
    sup.update(9.0)
    robots, tasks, alarms = state(sup, 9.0)
    assert tasks["n2"][0] == "cancelled" and ("task_unattended", "n2") not in alarms
    sup.restart(0.0)  # a new run: the old run's submissions are gone
    assert "n1" not in state(sup, 0.0)[1]


def test_a_view_started_after_submissions_asks_the_intake_for_them(patrol):
    """A picture attached after tasks entered the run asks the intake's `tasks/history` once
    the intake's token is up (supervisor/live/api.py, ask_history): the submitted task joins
    it, the cancelled one is `cancelled` — with nothing heard live."""
    import time
    from mrta_zenoh.tasks.intake import Intake
    from mrta_zenoh.tasks.messages import HISTORY, Op, Request
    from mrta_zenoh.tasks.server import TOKEN

    app, arch = patrol
    own = app.tasks()[0]
    intake = Intake(lambda tid, fields: None, known=app.tasks())
    intake.offer("op", Request(Header("op", 0.0, 0), "a", str(Op.SUBMIT), "n1", "{}"))
    intake.offer("op", Request(Header("op", 0.0, 0), "b", str(Op.CANCEL), own))
    intake.release(1.0)
    net = InProcNetwork()
    with InProcBus(net) as server, InProcBus(net) as watcher:
        sup = Supervisor(arch, app, 0.0)
        handles = attach(sup, watcher, ManualClock(2.0))
        assert "n1" not in state(sup, 2.0)[1]  # no intake yet: nothing asked
        with server.answer_queries(HISTORY, intake.history), server.declare_token(TOKEN):
            deadline = time.monotonic() + 5.0  # asked on a thread of its own
            while sup.counts["task_changes"] < 2 and time.monotonic() < deadline:
                time.sleep(0.01)
        tasks = state(sup, 2.0)[1]
        assert "n1" in tasks and tasks[own][0] == "cancelled", tasks
        for h in handles:
            h.close()


def test_a_flood_of_invented_ids_costs_bounded_state(patrol):
    app, arch = patrol
    sup = Supervisor(arch, app, 0.0)
    mons = sup.monitors
    for i in range(20_000):
        rid = f"r{i}"
        sup.on_sample(mons, f"{rid}/alliance/inter_robot_communication", IRC,
                      InterRobotCommunication(Header(rid, 1.0, 0), f"t{i}", 60.0), 1.0)
        sup.on_sample(mons, "robot1/alliance/inter_robot_communication", IRC,
                      InterRobotCommunication(Header("robot1", 1.0, 0), "x" * 70 + str(i), 1.0), 1.0)
    assert len(sup.robots) == 3 and len(sup.tasks) == 3 and len(sup.allocations) == 0
    assert len(sup.unknown) == Supervisor.MAX_UNKNOWN
    assert len(sup.alarms) == Supervisor.MAX_UNKNOWN
    assert sup.counts["unknown_overflow"] == 20_000 - Supervisor.MAX_UNKNOWN
    assert sup.counts["field_errors"] == 20_000  # 74-character task ids are not ids
    assert len(sup._ids) <= 10_000
    assert len(json.dumps(sup.snapshot(1.0))) < 100_000


def test_a_stopped_clock_makes_robots_unknown_and_a_restart_drops_stale_states(patrol):
    app, arch = patrol
    sup = Supervisor(arch, app, 0.0)
    sup.on_liveliness("robot1/alliance/agent", True, 0.0)
    irc(sup, sup.monitors, "robot1", "wander", 50.0)
    sup.on_clock(True, 50.0)
    robots, _, alarms = state(sup, 50.0)
    assert robots["robot1"][0] == "unknown" and ("clock_stopped", "clock") in alarms
    sup.on_clock(False, 50.0)
    assert state(sup, 50.0)[0]["robot1"][0] == "busy"
    sup.restart(0.5)  # a new simulation run: time went back to 0
    robots, tasks, alarms = state(sup, 0.5)
    assert robots["robot1"] == ("idle", None) and tasks["wander"] == ("unallocated", [])
    assert ("clock_stopped", "clock") not in alarms



def test_every_tool_refreshes_alike_a_stall_and_a_new_run(patrol):
    """`Refresh` is what supervise, view and the demo call: on simulation time it raises
    `clock_stopped` when the clock stops, and drops the old run's states when time restarts."""
    app, arch = patrol
    wall = [0.0]
    clock = SimClock(silence=2.0, wall=lambda: wall[0])
    clock.on_clock(50.0, "run-a")
    sup = Supervisor(arch, app, clock.now())
    refresh = Refresh(sup, clock, sim_time=True)
    sup.on_liveliness("robot1/alliance/agent", True, 50.0)
    irc(sup, sup.monitors, "robot1", "wander", 50.0)
    assert refresh() == 50.0 and state(sup, 50.0)[0]["robot1"][0] == "busy"
    wall[0] = CLOCK_STALL  # no clock sample for CLOCK_STALL wall seconds
    refresh()
    robots, _, alarms = state(sup, 50.0)
    assert robots["robot1"][0] == "unknown" and ("clock_stopped", "clock") in alarms
    clock.on_clock(0.5, "run-b")  # the old source silent: a new run, time back to 0.5
    assert refresh() == 0.5
    robots, tasks, alarms = state(sup, 0.5)
    assert robots["robot1"] == ("idle", None) and tasks["wander"] == ("unallocated", [])
    assert ("clock_stopped", "clock") not in alarms
    # on wall time neither applies: the same stall raises nothing
    sup2 = Supervisor(arch, app, 0.0)
    Refresh(sup2, clock, sim_time=False)()
    wall[0] += 10 * CLOCK_STALL
    Refresh(sup2, clock, sim_time=False)()
    assert ("clock_stopped", "clock") not in state(sup2, 0.5)[2]


OTHER_ARCH = textwrap.dedent("""\
    <rqt_mrta><architecture><name>Market</name>
      <robots><type>MT</type>
        <busy_robots><topic><name>market/award</name><type>market_msgs/Award</type>
          <field>winner/name</field><queue_size>5</queue_size><timeout>1.0</timeout></topic></busy_robots>
        <idle_robots><topic><name>fleet/*/heartbeat</name><type>market_msgs/Heartbeat</type>
          <field>robot</field><queue_size>5</queue_size><timeout>1.0</timeout></topic></idle_robots>
      </robots>
      <tasks><type>MR</type>
        <incoming_tasks><topic><name>market/offer</name><type>market_msgs/Offer</type>
          <field>jobs/0</field><queue_size>5</queue_size><timeout>1.0</timeout></topic></incoming_tasks>
      </tasks>
      <allocations><type>TA</type>
        <allocated_tasks><topic><name>market/award</name><type>market_msgs/Award</type>
          <field>job</field><queue_size>5</queue_size><timeout>1.0</timeout></topic></allocated_tasks>
      </allocations></architecture></rqt_mrta>""")


def test_a_different_architecture_drives_the_same_supervisor_over_a_bus(tmp_path):
    (tmp_path / "arch.xml").write_text(OTHER_ARCH)
    arch = load_rqt_mrta(tmp_path / "arch.xml")
    app = ApplicationFile("market", "Warehouse", [RobotEntry("amr1", ["pick", "drop"]),
                                                  RobotEntry("amr2", ["pick", "drop"])])
    clock = ManualClock(0.0)
    net = InProcNetwork()
    with InProcBus(net) as watcher, InProcBus(net) as fleet:
        sup = Supervisor(arch, app, 0.0)
        handles = attach(sup, watcher, clock)
        fleet.publish("fleet/amr1/heartbeat", GenericMessage("market_msgs/Heartbeat", {"robot": "amr1"}))
        fleet.publish("fleet/amr2/heartbeat", GenericMessage("market_msgs/Heartbeat", {"robot": "amr2"}))
        fleet.publish("market/offer", GenericMessage("market_msgs/Offer", {"jobs": ["drop", "x"]}))
        fleet.publish("market/award", GenericMessage("market_msgs/Award",
                                                     {"winner": {"name": "amr2"}, "job": "pick"}))
        fleet.publish("market/award", GenericMessage("market_msgs/Bid", {"winner": {"name": "amr1"}}))
        robots, tasks, _ = state(sup, 0.0)
        assert robots == {"amr1": ("idle", None), "amr2": ("busy", "pick")}
        assert tasks == {"pick": ("allocated", ["amr2"]), "drop": ("incoming", [])}
        assert sup.counts["wrong_type"] == 1
        clock.set(1.5)
        sup.update(1.5)
        robots, tasks, _ = state(sup, 1.5)
        # no tokens in this architecture: a robot whose messages stop is offline, and alarmed
        assert robots == {"amr1": ("offline", None), "amr2": ("offline", None)}
        assert ("messages_stopped", "amr2") in state(sup, 1.5)[2]
        for h in handles:
            h.close()


class _Done(TaskWatch):
    """Task news on `fleet/news`: the message's job is done."""

    def feed(self):
        return [("fleet/news", None)]  # any type

    def read(self, key, message):
        return TaskStatus(message.data["job"], "done")


def test_a_supervisor_nobody_sees_hears_only_the_task_news(tmp_path):
    """A mission runner with no view (`mrta -q demo`, a study's run) attaches its supervisor
    unshown: the monitors' samples are not decoded for nobody, the task news still end the run."""
    (tmp_path / "arch.xml").write_text(OTHER_ARCH)
    arch = load_rqt_mrta(tmp_path / "arch.xml")
    app = ApplicationFile("market", "Warehouse", [RobotEntry("amr1", ["pick", "drop"])])
    clock = ManualClock(0.0)
    net = InProcNetwork()
    with InProcBus(net) as watcher, InProcBus(net) as fleet:
        sup = Supervisor(arch, app, 0.0, watch=_Done())
        handles = attach(sup, watcher, clock, shown=False)
        fleet.publish("fleet/amr1/heartbeat", GenericMessage("market_msgs/Heartbeat",
                                                             {"robot": "amr1"}))
        fleet.publish("market/award", GenericMessage("market_msgs/Award",
                                                     {"winner": {"name": "amr1"}, "job": "pick"}))
        assert sup.counts["samples"] == 0 and not sup.all_done()
        for job in ("pick", "drop"):
            fleet.publish("fleet/news", GenericMessage("market_msgs/News", {"job": job}))
        assert sup.all_done() and sup.counts["task_news"] == 2
        for h in handles:
            h.close()
        shown = attach(sup, watcher, clock)  # the same supervisor, seen: the monitors too
        fleet.publish("fleet/amr1/heartbeat", GenericMessage("market_msgs/Heartbeat",
                                                             {"robot": "amr1"}))
        assert sup.counts["samples"] == 1
        for h in shown:
            h.close()


def test_ros_style_names_become_key_expressions():
    assert Topic("/alliance/inter_robot_communication", "t", "f").key_expr == \
        "**/alliance/inter_robot_communication"
    assert Topic("*/alliance/x", "t", "f").key_expr == "*/alliance/x"


def test_our_architecture_file_is_what_the_supervisor_reads():
    arch = load_rqt_mrta(ALLIANCE_ARCH / "rqt_mrta.xml")
    sup = Supervisor(arch, ApplicationFile("alliance", "x", [RobotEntry("r1", ["t"])]), 0.0)
    assert {m.role for m in sup.monitors} == {"busy_robots", "allocated_tasks"}


def test_live_view_fits_80_by_24_with_ten_robots(patrol):
    import io

    from rich.console import Console

    from mrta_supervisor.live.view import render

    app, arch = patrol
    app = ApplicationFile(app.architecture, app.name,
                          [RobotEntry(f"robot{i}", ["wander", "border_protection", "report"])
                           for i in range(1, 11)])
    sup = Supervisor(arch, app, 0.0, unattended_after=1.0)
    for i in range(1, 11):
        sup.on_liveliness(f"robot{i}/alliance/agent", True, 0.0)
    for i, task in ((1, "wander"), (2, "border_protection"), (3, "report")):
        irc(sup, sup.monitors, f"robot{i}", task, 1.0)
    sup.update(5.0)
    sup.on_liveliness("robot7/alliance/agent", False, 5.0)
    buf = io.StringIO()
    Console(file=buf, width=80, height=24, color_system=None).print(render(sup.snapshot(5.0), 80))
    lines = buf.getvalue().rstrip("\n").splitlines()
    assert len(lines) <= 24 and max(len(x) for x in lines) <= 80, "\n".join(lines)
    text = buf.getvalue()
    assert "robot10" in text and "offline" in text and "ALARM communication_lost robot7" in text
    assert "border_protection" in text  # never cut to "border_prote…"


def test_ids_with_markup_and_escape_codes_are_shown_as_plain_text(patrol):
    """A task id holding rich markup or terminal escapes neither breaks nor styles the view."""
    import io

    from rich.console import Console

    from mrta_supervisor.live.view import render

    app, arch = patrol
    sup = Supervisor(arch, app, 0.0)
    snap = sup.snapshot(1.0)
    snap["tasks"].append({"id": "[/x][bold red]boom\x1b[2J", "state": "unallocated",
                          "robots": [], "since": 0.0})
    buf = io.StringIO()
    Console(file=buf, width=80, color_system="truecolor", force_terminal=True).print(
        render(snap, 80))
    out = buf.getvalue()
    assert "[/x][bold red]boom\\x1b[2J" in out  # literally, escape made visible
    assert "\x1b[2J" not in out


def test_a_route_executing_robot_shows_the_task_it_serves_not_the_first_it_holds():
    """SSI's robots hold queues: robot1 holds t2 and t3 and is on t3. The supervisor names the
    task its own Progress says it is on, and the queue beside it (the monitors' sorted set
    would say t2)."""
    from mrta_zenoh.architectures import architecture
    from mrta_zenoh.toolchain.registry import Registry
    from mrta_agent.route.messages import Progress, Queued
    from mrta_supervisor.live.entities import Serving

    ssi = architecture("ssi")
    app = ApplicationFile("delivery", "Delivery", [RobotEntry("robot1", ["t1", "t2", "t3"]),
                                                   RobotEntry("robot2", ["t1", "t2", "t3"])])
    clock = ManualClock(10.0)
    net = InProcNetwork()
    with InProcBus(net) as watcher, InProcBus(net) as fleet:
        sup = Supervisor(Registry().architecture("ssi")[1], app, 10.0, serving=Serving(ssi))
        handles = attach(sup, watcher, clock)
        for place, task in enumerate(["t3", "t2"]):  # its route: t3 first, then t2
            fleet.publish(f"robot1/ssi/queued/{task}", Queued(Header("robot1", 10.0, 0), task,
                                                                place))
        fleet.publish("robot1/ssi/progress", Progress(Header("robot1", 10.0, 0), "t3", "",
                                                      ("t3", "t2"), (), 0.0, 0.0, 0.0))
        snap = {r["id"]: r for r in sup.snapshot(10.0)["robots"]}
        assert (snap["robot1"]["task"], snap["robot1"]["queue"]) == ("t3", ["t3", "t2"])
        assert (snap["robot2"]["task"], snap["robot2"]["queue"]) == (None, [])
        # a report between tasks: the robot is on none, its queue still holds t2
        fleet.publish("robot1/ssi/progress", Progress(Header("robot1", 11.0, 0), "", "t3",
                                                      ("t2",), ("t3",), 0.0, 0.0, 0.0))
        clock.set(11.0)
        snap = {r["id"]: r for r in sup.snapshot(11.0)["robots"]}
        assert (snap["robot1"]["task"], snap["robot1"]["queue"]) == (None, ["t2"])
        # a forged report (robot2's key, robot1's header) says nothing
        fleet.publish("robot2/ssi/progress", Progress(Header("robot1", 11.0, 0), "t1", "",
                                                      ("t1",), (), 0.0, 0.0, 0.0))
        assert {r["id"]: r["task"] for r in sup.snapshot(11.0)["robots"]}["robot2"] is None
        for h in handles:
            h.close()
