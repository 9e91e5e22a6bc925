"""`mrta sim` as its own process, driven by a separate commander process over real Zenoh."""

import json
import signal

import pytest

from mrta_simulator.robot_model import RobotModel

pytestmark = pytest.mark.multiprocess

M = RobotModel()


@pytest.mark.slow
def test_sim_process_moves_a_robot_on_command_and_its_watchdog_stops_it(children, tokens,
                                                                         tmp_path):
    snap = tmp_path / "world.png"
    sim = children.mrta("sim", "--world", "patrol", "--robot", "robot1=-15,-4,0",
                        "--robot", "robot2", "--speed", "2", "--snapshot", str(snap), name="sim")
    tokens.wait("@mrta/clock_source/*", 30, sim)
    # the commander follows the simulator's clock, drives, then reports
    cmd = children.python("commander.py", "robot1", "0.5", "6", name="commander")
    report = json.loads(cmd.wait_line(lambda line: line.startswith("{"), 60))
    (_, x0, y0), (_, x1, y1) = report["start"], report["at_silence"]
    # the robot drove along +x for the commanded time, give or take one network/step latency
    expected = 0.5 * report["commanded_for"] - 0.5 ** 2 / (2 * M.linear_accel)
    assert x1 - x0 == pytest.approx(expected, abs=0.15)
    assert abs(y1 - y0) < 0.01
    # silence → watchdog → stop: no further motion beyond watchdog + braking distance
    x_end = report["end"][1]
    assert 0.1 < x_end - x1 < 0.5 * M.watchdog + 0.5 ** 2 / (2 * M.linear_accel) + 0.15
    # sensors flow at 10 Hz of simulated time: ~9 s of sim → ~90 of each; the bumper of a
    # robot that touches nothing only as its once-a-second heartbeat
    for kind in ("sonar", "odom"):
        assert report["counts"][kind] >= 50, report["counts"]
    assert 5 <= report["counts"]["bumper"] <= report["counts"]["sonar"] // 5, report["counts"]
    assert len(report["first_sonar"]) == 8
    sim.signal(signal.SIGINT)
    assert sim.wait(10) == 130  # Ctrl-C: the shell's 128 + SIGINT, after a clean finish
    assert snap.stat().st_size > 10_000 and snap.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert any("done:" in line for line in sim.stderr)
