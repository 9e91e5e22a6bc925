"""The simulation on its own, in simulated time: motion, walls, sonar, watchdog, determinism."""

import math

import numpy as np
import pytest

from mrta_simulator.engine import DT, Simulation
from mrta_simulator.robot_model import RobotModel
from mrta_simulator.sonar import ray_walls, sonar_origins
from mrta_simulator.world import Pose, World

BOX = World("box", np.array([[-20, -20, 20, -20], [20, -20, 20, 20],
                             [20, 20, -20, 20], [-20, 20, -20, -20]], dtype=float))
M = RobotModel()


def drive(sim, rid, lin, ang, seconds, each=None):
    for _ in range(int(round(seconds / DT))):
        sim.command(rid, lin, ang)
        sim.step()
        if each:
            each(sim)


def test_forward_motion_matches_v_t_after_acceleration():
    sim = Simulation(BOX, {"r": Pose(0, 0, 0)})
    drive(sim, "r", 0.5, 0.0, 10.0)
    expected = 0.5 * 10.0 - 0.5 ** 2 / (2 * M.linear_accel)  # minus the ramp-up
    assert sim.pose[0, 0] == pytest.approx(expected, abs=0.02)
    assert abs(sim.pose[0, 1]) < 1e-6 and abs(sim.pose[0, 2]) < 1e-6
    assert sim.distance[0] == pytest.approx(expected, abs=0.02)


def test_speed_is_capped_and_turning_follows_the_angular_command():
    sim = Simulation(BOX, {"r": Pose(0, 0, 0)})
    drive(sim, "r", 5.0, 0.0, 6.0)
    assert sim.vel[0, 0] == pytest.approx(M.max_linear)
    sim2 = Simulation(BOX, {"r": Pose(0, 0, 0)})
    drive(sim2, "r", 0.0, 0.5, 3.0)
    ramp = 0.5 ** 2 / (2 * M.angular_accel)
    assert sim2.pose[0, 2] == pytest.approx(0.5 * 3.0 - ramp, abs=0.01)
    assert np.hypot(*sim2.pose[0, :2]) < 1e-3  # turning in place does not translate


def test_robot_stops_at_a_wall_never_passes_through_and_reports_a_stall():
    sim = Simulation(BOX, {"r": Pose(15, 0, 0)})
    limit = 20 - 0.02 - M.radius  # wall centre line minus its half thickness and our radius
    xs = []
    drive(sim, "r", 0.75, 0.0, 20.0, each=lambda s: xs.append(s.pose[0, 0]))
    assert max(xs) < limit + 0.03
    assert xs[-1] > limit - 0.05  # it did get there
    assert sim.stalled[0] and sim.collisions[0] == 1 and sim.contacts[0] == 1


def test_sonars_3_and_4_read_one_metre_from_a_wall_one_metre_ahead():
    front = 0.166  # sonar 3/4 transducers sit 166 mm ahead of the centre
    sim = Simulation(BOX, {"r": Pose(20 - 1.0 - front, 0, 0)}, seed=3)
    ranges = sim.sonar().ranges[0]
    # the beam's near edge (10° − 7.5°) meets the wall first
    assert ranges[3] == pytest.approx(1.0 / math.cos(math.radians(2.5)), abs=0.05)
    assert ranges[4] == pytest.approx(1.0 / math.cos(math.radians(2.5)), abs=0.05)
    assert ranges[0] == M.sonar_max and ranges[7] == M.sonar_max  # side beams: no echo


def test_exact_geometry_without_noise():
    sonars = M.sonar_poses()
    origins, dirs = sonar_origins(np.array([[0.0, 0.0, 0.0]]), sonars)
    wall = np.array([[2.0, -5, 2.0, 5]])
    axis = ray_walls(origins, dirs, wall, 5.0)  # a single ray along each axis
    expected = (2.0 - sonars[:, 0]) / np.cos(sonars[:, 2])
    expected[[0, 7]] = np.inf  # parallel to the wall
    np.testing.assert_allclose(axis, expected, rtol=1e-9)
    cone = ray_walls(origins, dirs, wall, 5.0, np.radians(7.5))
    near_edge = np.maximum(np.abs(sonars[:, 2]) - np.radians(7.5), 0.0)
    expected = (2.0 - sonars[:, 0]) / np.cos(near_edge)
    expected[[0, 7]] = np.inf  # the ±82.5° edge meets the wall beyond 5 m
    np.testing.assert_allclose(cone, expected, rtol=1e-9)
    # a short segment entirely inside beam 3's cone, off its axis: nearest end point counts
    tiny = np.array([[1.0, 0.1, 1.0, 0.12]])
    r = ray_walls(origins[3:4], dirs[3:4], tiny, 5.0, np.radians(7.5))
    assert r[0] == pytest.approx(np.hypot(1.0 - 0.166, 0.1 - 0.027))


def test_another_robot_is_seen_and_without_it_there_is_no_echo():
    alone = Simulation(BOX, {"a": Pose(0, 0, 0)})
    assert alone.sonar().ranges[0, 3] == M.sonar_max
    sim = Simulation(BOX, {"a": Pose(0, 0, 0), "b": Pose(2.0, 0, 0)})
    r = sim.sonar().ranges
    # 2 m − 0.166 m (transducer) − 0.26 m (b's radius), seen at the beam's edge
    assert 1.5 < r[0, 3] < 1.65 and 1.5 < r[0, 4] < 1.65
    assert r[1, 3] == M.sonar_max  # b faces away: its front beams see nothing


def test_watchdog_stops_a_robot_whose_commands_stop():
    sim = Simulation(BOX, {"r": Pose(0, 0, 0)})
    drive(sim, "r", 0.5, 0.0, 3.0)
    x_at_silence = sim.pose[0, 0]
    sim.advance(M.watchdog + 0.5 / M.linear_accel + 0.1)  # watchdog, then braking
    assert sim.vel[0, 0] == 0.0
    x_stopped = sim.pose[0, 0]
    sim.advance(2.0)
    assert sim.pose[0, 0] == x_stopped
    # it kept going for the watchdog period at full speed, then braked
    assert x_stopped - x_at_silence == pytest.approx(
        0.5 * M.watchdog + 0.5 ** 2 / (2 * M.linear_accel), abs=0.03)


@pytest.mark.slow
def test_same_seed_and_commands_give_the_same_run_and_another_seed_other_noise():
    def run(seed):
        sim = Simulation(BOX, {"a": Pose(0, 0, 0), "b": Pose.from_degrees(3, 1, 180), "c": Pose.from_degrees(-3, 2, 45)},
                         seed=seed)
        rows = []
        for k in range(400):
            sim.command("a", 0.6, 0.3 * math.sin(k / 40))
            sim.command("b", 0.4, -0.2)
            if k < 200:
                sim.command("c", 0.7, 0.0)
            sim.step()
            if k % 5 == 0:
                rows.append((sim.pose.copy(), sim.odom.copy(), sim.sonar().ranges))
        return rows

    one, two, other = run(7), run(7), run(8)
    for (p1, o1, s1), (p2, o2, s2) in zip(one, two):
        np.testing.assert_array_equal(p1, p2)
        np.testing.assert_array_equal(o1, o2)
        np.testing.assert_array_equal(s1, s2)
    assert not np.array_equal(one[-1][2], other[-1][2])  # sonar noise follows the seed
    np.testing.assert_array_equal(one[-1][0], other[-1][0])  # physics does not depend on it


def test_odometry_drifts_from_ground_truth_but_stays_close():
    sim = Simulation(BOX, {"r": Pose(0, 0, 0)}, seed=1)
    drive(sim, "r", 0.5, 0.2, 30.0)
    err = np.hypot(*(sim.odom[0, :2] - sim.pose[0, :2]))
    assert 1e-4 < err < 0.1 * sim.distance[0]


def test_robots_collide_with_each_other():
    sim = Simulation(BOX, {"a": Pose(0, 0, 0), "b": Pose.from_degrees(2, 0, 180)})
    drive(sim, "a", 0.5, 0.0, 6.0)
    gap = np.hypot(*(sim.pose[0, :2] - sim.pose[1, :2]))
    assert gap > 2 * M.radius - 0.03
    assert sim.collisions[0] >= 1 and sim.collisions[1] >= 1


def test_non_finite_command_is_refused():
    sim = Simulation(BOX, {"r": Pose(0, 0, 0)})
    with pytest.raises(ValueError, match="non-finite"):
        sim.command("r", float("nan"), 0.0)
