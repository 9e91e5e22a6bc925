"""The patrol layers in the simulator, in simulated time; and the patrol evaluators."""

import math

import numpy as np
import pytest

from mrta_zenoh.bus.inproc import InProcBus, InProcNetwork
from mrta_zenoh.clock import ManualClock
from mrta_zenoh.messages import Header, Point2D, PointCloud
from tests.harness.helpers import PATROL_WORLD
from mrta_agent.runtime.builtin import PointCloudSensor
from mrta_agent.runtime.params import SensorParams
from mrta_patrol.evaluators import ReportDue, WallInRange
from mrta_patrol.layers import BorderProtection, ReportParams, Wander
from mrta_patrol.messages import Report
from mrta_agent.runtime.plugins import AgentContext
from mrta_simulator.engine import Simulation
from mrta_simulator.world import load_world
from tests.harness.layer_harness import LayerRun, typed_sections

WORLD = load_world(PATROL_WORLD)


@pytest.mark.slow
def test_wander_moves_through_open_space_without_a_collision_for_120_s():
    for seed in (0, 1):
        sim = Simulation(WORLD, {"robot1": WORLD.starts["robot1"]}, seed=seed)
        run = LayerRun(sim, "robot1", Wander, seed=seed)
        run.run(120.0)
        assert sim.collisions[0] == 0
        assert sim.distance[0] > 30.0  # it keeps moving (0.5 m/s cruise, slower near walls)


@pytest.mark.slow
def test_wander_avoids_other_robots_too():
    sim = Simulation(WORLD, {"robot1": WORLD.starts["robot1"], "robot4": WORLD.starts["robot4"],
                             "robot2": WORLD.starts["robot2"]}, seed=3)
    run = LayerRun(sim, "robot1", Wander, seed=3)
    run.run(60.0)
    assert sim.collisions[0] == 0


def _wall_distance(x, y):
    return min(x + 20, 20 - x, y + 6, 6 - y)


@pytest.mark.slow
def test_border_protection_keeps_its_distance_and_goes_round_the_perimeter():
    sim = Simulation(WORLD, {"robot2": WORLD.starts["robot2"]}, seed=1, record_trails=True)
    run = LayerRun(sim, "robot2", BorderProtection)
    dist = []
    run.run(300.0, each=lambda r: dist.append(_wall_distance(*r.sim.pose[0, :2])))
    dist = np.array(dist)
    reached = int(np.argmax(dist < 1.5))  # first time at the wall
    assert 0 < reached < 200  # within 20 s of starting (it starts 3 m from the nearest wall)
    band = dist[reached:]
    set_point = 1.0 + 0.15  # layer distance, seen from the centre (sonar 7 is 136 mm off-axis)
    assert np.mean(np.abs(band - set_point) < 0.35) > 0.95, np.percentile(band, [1, 50, 99])
    assert sim.collisions[0] == 0
    # it advances along the wall: the trail passes near most of the perimeter
    trail = np.stack(sim.trails)[:, 0, :]
    cells = [(x, y) for x in np.arange(-19.5, 20, 1.0) for y in (-6.0, 6.0)] + \
            [(x, y) for x in (-20.0, 20.0) for y in np.arange(-5.5, 6, 1.0)]
    seen = [np.min(np.hypot(trail[:, 0] - x, trail[:, 1] - y)) < 2.0 for x, y in cells]
    assert np.mean(seen) > 0.9


@pytest.fixture
def ctx():
    net = InProcNetwork()
    bus = InProcBus(net)
    sections = typed_sections(WallInRange, ReportDue)
    yield AgentContext("robot1", bus, ManualClock(10.0), np.random.default_rng(0), {}, sections), bus
    bus.close()


def cloud(*ranges_angles):
    return PointCloud(Header("robot1", 10.0, 0), tuple(
        Point2D(r * math.cos(math.radians(a)), r * math.sin(math.radians(a)))
        for r, a in ranges_angles))


def test_wall_in_range_needs_a_fresh_echo_within_range(ctx):
    c, _ = ctx
    s = PointCloudSensor(SensorParams("alliance/point_cloud", "sonar", 1.0, 1.0))
    ev = WallInRange("border_protection", [s])
    ev.setup(c)
    assert not ev.is_applicable(10.0)  # nothing heard yet
    s.on_message(cloud((5.0, 0), (5.0, 90)), 10.0)
    assert not ev.is_applicable(10.0)  # only "no echo"
    s.on_message(cloud((5.0, 0), (3.0, -90)), 10.0)
    assert ev.is_applicable(10.0)
    assert not ev.is_applicable(11.5)  # stale


def test_report_due_until_someone_reports_then_again_after_the_period(ctx):
    c, bus = ctx
    s = PointCloudSensor(SensorParams("alliance/point_cloud", "sonar", 1.0, 1.0))
    s.on_message(cloud((2.0, 0)), 10.0)
    ev = ReportDue("report", [s])
    ev.setup(c)
    assert ev.is_applicable(10.0)
    bus.publish("robot3/patrol/report", Report(Header("robot3", 10.0, 0), 12.0, 0.3, ()))
    assert not ev.is_applicable(10.0)
    c.clock.set(10.0 + c.section("Report", ReportParams).period)
    s.on_message(cloud((2.0, 0)), c.clock.now())
    assert ev.is_applicable(c.clock.now())


def test_shutdown_closes_every_subscription_a_plugin_opened(ctx):
    c, bus = ctx
    s = PointCloudSensor(SensorParams("alliance/point_cloud", "sonar", 1.0, 1.0))
    ev = ReportDue("report", [s])
    s.setup(c)
    ev.setup(c)
    assert len(bus._subs) == 2
    ev.shutdown()
    s.shutdown()
    assert bus._subs == []


def test_the_ledger_counts_only_teammates_and_finite_distances(ctx):
    """A NaN odometry sample must not poison later reports, nor a forged robot9 appear in
    them. A robot logs its own work from its own odometry and doing feed:
    another robot's odometry or feed, and a sample on its key claiming another robot, add
    nothing; teammates' work comes only in their logs (tests/test_patrol_ledger.py)."""
    import msgpack

    from mrta_patrol.layers import ReportLayer
    from mrta_zenoh.codec import encoding_for
    from mrta_zenoh.messages import Odometry, Pose2D, Twist
    from mrta_agent.alliance.messages import Motivation

    from mrta_zenoh.architectures import architecture

    c, bus = ctx
    c.architecture = architecture("alliance")  # the ledger reads the robot's architecture
    c.sections.update(typed_sections(ReportLayer))
    layer = ReportLayer()
    layer.setup(c)
    tokens = [bus.declare_token(f"robot{i}/alliance/agent") for i in (1, 2)]

    def odom(robot, x):
        bus.publish(f"{robot}/odom", Odometry(Header(robot, 10.0, 0), Pose2D(x, 0.0, 0.0),
                                              Twist(0.0, 0.0)))

    odom("robot1", 0.0)
    odom("robot1", 3.0)
    nan = {"header": {"frame_id": "robot1", "stamp": 10.0, "seq": 0},
           "pose": {"x": float("nan"), "y": 0.0, "theta": 0.0}, "twist": {"linear": 0.0, "angular": 0.0}}
    bus.publish_raw("robot1/odom", encoding_for("mrta_msgs/Odometry"), msgpack.packb(nan))
    odom("robot1", 4.0)
    odom("robot2", 0.0)
    odom("robot2", 50.0)  # a teammate's odometry: its own log says what it did
    odom("robot9", 0.0)
    odom("robot9", 100.0)  # not a teammate: no token
    def doing(key, robot, t):
        bus.publish(key, Motivation(Header(robot, t, 0), "border_protection", 1.0, False,
                                    False, False, True, 100.0, 100.0, True))

    for i in range(6):  # 0.5 s of ticks; the ledger's clock moves with them
        c.clock.set(10.0 + i / 10)
        doing("robot1/alliance/motivation/border_protection", "robot1", 10.0 + i / 10)
        doing("robot2/alliance/motivation/border_protection", "robot2", 10.0 + i / 10)
        doing("robot9/alliance/motivation/border_protection", "robot9", 10.0 + i / 10)
        doing("robot1/alliance/motivation/wander", "robot2", 10.0 + i / 10)  # forged
    report = layer.ledger.report("robot1", 12.0)
    assert report.distance == 4.0 and math.isfinite(report.distance)
    times = {(tt.robot_id, tt.task_id): tt.seconds for tt in report.task_times}
    assert set(times) == {("robot1", "border_protection")}  # the others add nothing
    assert abs(times[("robot1", "border_protection")] - 0.5) < 1e-9
    assert bus.stats["malformed"] == 1
    layer.shutdown()
    for t in tokens:
        t.close()


@pytest.mark.parametrize("section,key,value,text", [
    ("Wander", "speed", "1.0e+308", "<= 10.0"),
    ("Wander", "turn_rate", "0.0", "> 0.0"),
    ("BorderProtection", "x_max", "1.0e+300", "<= 10000.0"),
    ("Report", "period", "1.0e-300", ">= 0.001"),
    ("Report", "speed", ".inf", "finite"),
    ("Report", "log_period", "0.01", ">= 0.1"),
    ("Report", "log_period", "3600.0", "<= 60.0"),
])
def test_absurd_layer_parameters_are_refused_with_their_line(tmp_path, section, key, value, text):
    """Finite but absurd values get the file, the line and the bound."""
    from mrta_agent.runtime.params import load_layers_params
    from mrta_patrol.layers import BorderParams, WanderParams
    from mrta_zenoh.errors import ConfigError
    kinds = {"Wander": WanderParams, "BorderProtection": BorderParams, "Report": ReportParams}
    f = tmp_path / "layers.yaml"
    f.write_text(f"# a comment\n{section}:\n  {key}: {value}\n")
    with pytest.raises(ConfigError) as err:
        load_layers_params(f).convert((section,), kinds[section])
    assert f"layers.yaml:3: '{section}/{key}'" in str(err.value) and text in str(err.value)
