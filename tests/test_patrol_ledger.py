"""The patrol ledger fed by each robot's own log: a robot subscribes to its own
odometry and its own part of the architecture's doing feed, publishes its log once per period
whether or not its report behaviour is active, and merges its teammates' latest logs."""

import math

import numpy as np
import pytest

from mrta_zenoh.architectures import architecture
from mrta_zenoh.bus.inproc import InProcBus, InProcNetwork
from mrta_zenoh.clock import ManualClock
from mrta_zenoh.messages import Header, Odometry, Pose2D, Twist
from mrta_agent.alliance.messages import Motivation
from mrta_agent.runtime.plugins import AgentContext
from mrta_patrol.layers import ReportLayer
from mrta_patrol.messages import PatrolLog, TaskTime
from tests.harness.layer_harness import typed_sections

ALLIANCE = architecture("alliance")
CELLS = 208  # the patrol border, 40 m × 12 m, in 0.5 m cells


class Robot:
    """One robot's report layer (and so its ledger) on its own bus of a shared network, with
    its agent token; the test publishes its odometry and its Motivation as the simulator and
    its agent would."""

    def __init__(self, net, clock, robot_id, arch=ALLIANCE, **report):
        self.id = robot_id
        self.bus = InProcBus(net)
        sections = typed_sections(ReportLayer)
        if report:
            key = next(k for k in sections if k[0] == "Report")
            sections[key] = type(sections[key])(**report)
        self.ctx = AgentContext(robot_id, self.bus, clock, np.random.default_rng(0), {},
                                sections, architecture=arch)
        self.layer = ReportLayer()
        self.layer.setup(self.ctx)
        self.ledger = self.layer.ledger
        self.token = self.bus.declare_token(arch.agent_token(robot_id))

    def odom(self, x, y, t):
        self.bus.publish(f"{self.id}/odom", Odometry(Header(self.id, t, 0), Pose2D(x, y, 0.0),
                                                    Twist(0.0, 0.0)))

    def doing(self, task, t, active=True):
        self.bus.publish(ALLIANCE.key(self.id, "motivation", task),
                         Motivation(Header(self.id, t, 0), task, 1.0, False, False, False, True,
                                    100.0, 100.0, active))

    def close(self):
        self.layer.shutdown()
        self.token.close()
        self.bus.close()


@pytest.fixture
def team():
    net, clock = InProcNetwork(), ManualClock(10.0)
    robots = []

    def make(robot_id, **kw):
        robots.append(Robot(net, clock, robot_id, **kw))
        return robots[-1]

    listener = InProcBus(net)
    logs = []
    listener.subscribe("*/patrol/log", lambda s: logs.append(s.message), msg_type=PatrolLog)
    yield make, clock, listener, logs
    for r in robots:
        r.close()
    listener.close()


def drive(clock, robots_paths, t0, t1, hz=10, doing=None):
    """Odometry at `hz` from t0 to t1 (both included) for each robot along its path(t), the
    clock moving with it; `doing`: (robot, task) pairs whose Motivation goes out each tick."""
    n = round((t1 - t0) * hz)
    for i in range(n + 1):
        t = t0 + i / hz
        clock.set(t)
        for robot, path in robots_paths:
            robot.odom(*path(t), t)
        for robot, task in doing or ():
            robot.doing(task, t)


def bottom(t):  # along the bottom wall, 1 m in: 0.4 m/s
    return -18.0 + 0.4 * (t - 10.0), -5.0


def top(t):  # along the top wall, the other way
    return 18.0 - 0.4 * (t - 10.0), 5.0


def test_the_ledger_subscribes_to_its_own_robots_feeds_and_the_logs_only(team):
    """Every robot hearing every robot's odometry and doing feed is N² traffic: the ledger
    hears its own robot's, and the teammates' logs."""
    make, clock, _, _ = team
    r1 = make("robot1")
    assert sorted(s.key_expr for s in r1.bus._subs) == [
        "*/patrol/log", "robot1/alliance/motivation/**", "robot1/odom"]
    murdoch = make("robot2", arch=architecture("murdoch"))
    assert sorted(s.key_expr for s in murdoch.bus._subs) == [
        "*/patrol/log", "robot2/murdoch/claim", "robot2/murdoch/release", "robot2/odom"]
    # and a teammate's odometry or doing feed indeed reaches nothing of robot1's ledger
    r3 = make("robot3")
    r3.odom(0.0, 0.0, 10.0)
    r3.odom(5.0, 0.0, 10.1)
    r3.doing("wander", 10.0)
    r3.doing("wander", 10.1)
    assert r1.ledger.distance == 0.0 and r1.ledger.task_time == {}


def test_the_log_goes_out_once_per_period_whether_or_not_the_layer_is_active(team):
    make, clock, _, logs = team
    r1 = make("robot1")
    drive(clock, [(r1, bottom)], 10.0, 15.0)  # never activated
    mine = [m for m in logs if m.header.frame_id == "robot1"]
    assert len(mine) == 5  # one per period, the first a period after the first sample
    r1.layer.on_activate(15.0)  # the report behaviour runs: the log goes on as before
    drive(clock, [(r1, bottom)], 15.1, 20.0)
    mine = [m for m in logs if m.header.frame_id == "robot1"]
    assert len(mine) == 10
    stamps = [m.header.stamp for m in mine]
    assert all(abs(b - a - 1.0) < 1e-6 for a, b in zip(stamps, stamps[1:]))
    assert [m.header.seq for m in mine] == list(range(1, 11))
    assert mine[-1].distance == pytest.approx(r1.ledger.distance - 0.4 * (20.0 - stamps[-1]))
    # a shorter log_period: more logs (the parameter is read)
    r2 = make("robot2", log_period=0.5)
    drive(clock, [(r2, top)], 30.0, 35.0)
    assert len([m for m in logs if m.header.frame_id == "robot2"]) == 10


def test_a_report_merges_its_own_work_with_each_teammates_latest_log(team):
    make, clock, _, logs = team
    r1, r2, r3 = make("robot1"), make("robot2"), make("robot3")
    drive(clock, [(r1, bottom), (r2, top), (r3, lambda t: (0.0, 0.0))], 10.0, 13.0,
          doing=[(r1, "wander"), (r2, "border_protection")])
    now = 13.05  # just after the last sample
    clock.set(now)
    last = {rid: [m for m in logs if m.header.frame_id == rid][-1] for rid in ("robot2", "robot3")}
    report = r1.ledger.report("robot1", now)
    # distance: its own, up to date, plus each teammate's latest log
    assert report.distance == pytest.approx(r1.ledger.distance + last["robot2"].distance
                                            + last["robot3"].distance)
    assert r1.ledger.distance == pytest.approx(0.4 * 3.0)
    # the border: its own cells ∪ its teammates'
    mine = r1.ledger.visited
    theirs = int.from_bytes(last["robot2"].visited, "little")
    assert mine and theirs and not mine & theirs  # opposite walls: no cell in common
    assert report.border_covered == pytest.approx((mine | theirs).bit_count() / CELLS)
    # task times: its own ∪ its teammates'
    times = {(tt.robot_id, tt.task_id): tt.seconds for tt in report.task_times}
    assert times == {("robot1", "wander"): pytest.approx(3.0),
                     ("robot2", "border_protection"): last["robot2"].task_times[0].seconds}
    assert last["robot2"].task_times == (TaskTime("robot2", "border_protection",
                                                  last["robot2"].task_times[0].seconds),)
    assert 1.0 <= times[("robot2", "border_protection")] <= 3.0
    # a teammate's log stamped at `now` or later waits for the next report (lockstep: it may
    # or may not have arrived by then)
    later = PatrolLog(Header("robot2", now, 99), 1000.0, CELLS, bytes(CELLS // 8), ())
    r2.bus.publish("robot2/patrol/log", later)
    assert r1.ledger.report("robot1", now) == report
    assert r1.ledger.report("robot1", now + 0.1).distance == pytest.approx(
        r1.ledger.distance + 1000.0 + last["robot3"].distance)


def test_a_dead_teammates_last_log_still_counts(team):
    """The takeover case: robot2's work before it died is part of every later report."""
    make, clock, _, logs = team
    r1, r2 = make("robot1"), make("robot2")
    drive(clock, [(r1, bottom), (r2, top)], 10.0, 12.0, doing=[(r2, "border_protection")])
    last = [m for m in logs if m.header.frame_id == "robot2"][-1]
    r2.token.close()  # robot2's agent is gone
    before = r1.ledger.report("robot1", 20.0)
    assert before.distance == pytest.approx(r1.ledger.distance + last.distance)
    assert ("robot2", "border_protection") in {(t.robot_id, t.task_id) for t in before.task_times}
    # what comes on its key after its token went is a stranger's, not robot2's work
    r2.bus.publish("robot2/patrol/log", PatrolLog(Header("robot2", 13.0, 50), 500.0, CELLS,
                                                  bytes(CELLS // 8), ()))
    assert r1.ledger.ignored["strangers"] == 1
    assert r1.ledger.report("robot1", 20.0) == before


@pytest.mark.parametrize("cells,visited", [
    (10, b"\x03\x00"),                          # another border's cell count
    (CELLS, bytes(CELLS // 8 - 1)),             # the right count, a bitmap too short
    (CELLS - 1, bytes(CELLS // 8)),             # a bitmap of the right size, one cell short
])
def test_a_log_for_another_border_is_counted_and_never_merged(team, cells, visited):
    make, clock, _, _ = team
    r1, r2 = make("robot1"), make("robot2")
    before = r1.ledger.report("robot1", 20.0)
    r2.bus.publish("robot2/patrol/log", PatrolLog(Header("robot2", 11.0, 1), 7.0, cells,
                                                  visited, ()))
    assert r1.ledger.ignored["other_border"] == 1
    assert r1.ledger.logs == {}
    assert r1.ledger.report("robot1", 20.0) == before


def test_forged_logs_add_nothing(team):
    """No token (robot9), a log on robot2's key claiming robot3, a task time about another
    robot, a negative time: each is counted and ignored; only robot2's own log counts."""
    make, clock, listener, _ = team
    r1 = make("robot1")
    make("robot2"), make("robot3")  # teammates: they hold their tokens
    empty = bytes(CELLS // 8)

    def log(key, frame, distance, times=()):
        listener.publish(key, PatrolLog(Header(frame, 11.0, 1), distance, CELLS, empty, times))

    log("robot9/patrol/log", "robot9", 100.0)
    log("robot2/patrol/log", "robot3", 100.0)
    log("robot2/patrol/log", "robot2", 100.0, (TaskTime("robot3", "wander", 5.0),))
    log("robot2/patrol/log", "robot2", 100.0, (TaskTime("robot2", "wander", -5.0),))
    log("robot1/patrol/log", "robot1", 100.0)  # its own key: its own log is authoritative
    assert r1.ledger.ignored == {"strangers": 1, "forged": 3}
    assert r1.ledger.report("robot1", 20.0).distance == 0.0
    log("robot2/patrol/log", "robot2", 2.5, (TaskTime("robot2", "wander", 5.0),))
    report = r1.ledger.report("robot1", 20.0)
    assert report.distance == 2.5
    assert report.task_times == (TaskTime("robot2", "wander", 5.0),)
    assert math.isfinite(report.border_covered) and report.border_covered == 0.0


def test_a_restarted_teammates_earlier_work_still_counts(team):
    """A new agent process for robot2 logs from seq 1 and distance 0 again: its first log used
    to replace the earlier process's, and the team's distance went down."""
    make, clock, _, _ = team
    r1, r2 = make("robot1"), make("robot2")

    def log(seq, stamp, distance, seconds):
        r2.bus.publish("robot2/patrol/log", PatrolLog(
            Header("robot2", stamp, seq), distance, CELLS, bytes(CELLS // 8),
            (TaskTime("robot2", "wander", seconds),)))

    log(1, 11.0, 3.0, 1.0)
    log(2, 12.0, 5.0, 2.0)   # the first process's last log
    log(1, 14.0, 0.5, 0.5)   # restarted: counts from 1 again
    clock.set(20.0)
    report = r1.ledger.report("robot1", 20.0)
    assert report.distance == pytest.approx(r1.ledger.distance + 5.0 + 0.5)
    times = {(t.robot_id, t.task_id): t.seconds for t in report.task_times}
    assert times[("robot2", "wander")] == pytest.approx(2.5)
    log(2, 15.0, 1.5, 1.0)   # the new process goes on: only its latest replaces its own
    report = r1.ledger.report("robot1", 20.0)
    assert report.distance == pytest.approx(r1.ledger.distance + 5.0 + 1.5)
