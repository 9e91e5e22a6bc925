"""The command line's rough edges: agents on wall time logged raw epoch
stamps, "1 robot were expected", `mrta sim --ros2` warned about its own agent's commands, and a
`.mrta-run.lock` stayed in every output folder after a run."""

from __future__ import annotations

import logging
import subprocess
import sys
from datetime import datetime

import numpy as np
import pytest

from mrta_agent.alliance.architecture import ALLIANCE
from mrta_agent.runtime.host import AgentOptions
from mrta_simulator.engine import Simulation
from mrta_simulator.node import SimNode
from mrta_simulator.world import Pose, World
from mrta_supervisor.mission.runner import LOCK_FILE, output_lock
from mrta_zenoh import keys
from mrta_zenoh.bus import InProcBus
from mrta_zenoh.clock import ManualClock
from mrta_zenoh.messages import Twist
from mrta_zenoh.timetext import at
from tests.harness.alliance_fixtures import robot_yaml, tasks_yaml, write
from tests.harness.helpers import free_port
from tests.test_agent_inproc import step

WALL = 1_795_715_420.53  # a wall-clock stamp: 2026-11-26


def clock_text(t: float) -> str:
    """The local time of day of `t` to the hundredth, as datetime writes it."""
    return datetime.fromtimestamp(round(t, 2)).strftime("%H:%M:%S.%f")[:11]


def test_a_stamp_reads_as_simulated_seconds_or_as_the_time_of_day():
    assert at(12.5) == "at t=12.50" and at(0.0) == "at t=0.00"
    assert at(7 * 86_400.0) == "at t=604800.00"  # the longest run (limits.RUN_DURATION)
    assert at(WALL) == "at " + clock_text(WALL)


def test_an_agent_on_wall_time_logs_activations_at_the_time_of_day(tmp_path, caplog):
    rf = write(tmp_path / "r.yaml", robot_yaml([{"task": "a", "fast": 25.0}]))
    tf = write(tmp_path / "t.yaml", tasks_yaml(["a"]))
    bus, clock = InProcBus(), ManualClock(WALL)
    agent = ALLIANCE.agent(ALLIANCE.prepare(AgentOptions("robot1", rf, tf)), bus, clock,
                           np.random.default_rng(1))
    agent.start()
    with caplog.at_level(logging.INFO, logger="mrta"):
        step(agent, bus, clock, 4)  # θ = 100 / 25: active on the 4th tick, at WALL + 0.3
    (line,) = [r.getMessage() for r in caplog.records if "activated a" in r.getMessage()]
    assert line.endswith(f"(threshold reached) at {clock_text(WALL + 0.3)}"), line
    assert "t=1795" not in line


def test_the_output_lock_goes_with_the_run_and_a_stale_one_is_taken_over(tmp_path):
    with output_lock(tmp_path):
        assert (tmp_path / LOCK_FILE).exists()
    assert not (tmp_path / LOCK_FILE).exists()
    (tmp_path / LOCK_FILE).write_text("123")  # a killed run's: unlocked
    with output_lock(tmp_path):
        assert (tmp_path / LOCK_FILE).read_text() != "123"
    assert list(tmp_path.iterdir()) == []


class FakeRos2Driver:
    """What SimNode asks of its ROS 2 driver: the robots it serves."""

    def __init__(self, command):
        self.nodes = {"robot2": None}

    def close(self):
        pass


def test_a_ros2_robots_own_agent_commands_are_counted_not_warned_about(caplog):
    """Its agent publishes robot2/cmd_vel, which the bridge carries to ROS 2: normal use."""
    world = World("box", np.array([[-20, -20, 20, -20], [20, -20, 20, 20],
                                   [20, 20, -20, 20], [-20, 20, -20, -20]], float))
    sim = Simulation(world, {"robot1": Pose(0, 0, 0), "robot2": Pose(5, 0, 0)})
    bus = InProcBus()
    node = SimNode(sim, bus, speed=0.0, ros2=FakeRos2Driver)
    with caplog.at_level(logging.DEBUG, logger="mrta"):
        for _ in range(3):
            bus.publish(keys.cmd_vel("robot2"), Twist(0.3, 0.0))
    assert node.stats.ros2_bypass_commands == 3
    assert [r.levelno for r in caplog.records if "robot2" in r.getMessage()] == [logging.DEBUG]


@pytest.mark.slow
@pytest.mark.multiprocess
def test_one_robot_was_expected(tmp_path):
    """`mrta sim --lockstep --wait-robots` with no agent exits 1 saying why, in English."""
    env = {"MRTA_RENDEZVOUS": f"tcp/127.0.0.1:{free_port()}", "PATH": "/usr/bin:/bin"}
    out = subprocess.run([sys.executable, "-m", "mrta_zenoh.cli.main", "sim", "--world",
                          "patrol", "--robot", "robot1", "--lockstep", "--wait-robots", "0.5",
                          "--duration", "1"], capture_output=True, text=True, timeout=120,
                         env=env)
    assert out.returncode == 1, out.stderr
    assert "although 1 robot was expected" in out.stderr, out.stderr
