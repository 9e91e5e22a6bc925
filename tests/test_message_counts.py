"""`messages` and every count in results.csv are reproducible for one seed: a
sample counts when it was *sent* in the mission's window — by its header stamp, or, for a
robot's headerless command, by the next stamped sample of its agent — not when the recorder
heard it. The expected counts are written out by hand from that definition."""

from __future__ import annotations

import subprocess
import sys

import pytest

from mrta_zenoh import codec
from mrta_zenoh.messages import Header, Odometry, Pose2D, Twist
from mrta_agent.alliance.architecture import ALLIANCE
from mrta_agent.alliance.messages import InterRobotCommunication
from mrta_supervisor.mission.analysis import message_rates

S = 1_000_000_000


def rec(key, msg, log_time):
    return (key, codec.encoding_for(msg.TYPE_NAME), round(log_time * S), codec.encode(msg))


def odom(robot, stamp):
    return Odometry(Header(robot, stamp, 0), Pose2D(0, 0, 0), Twist(0, 0))


def irc(robot, stamp):
    return InterRobotCommunication(Header(robot, stamp, 0), "wander", 10.0)


IRC = "robot1/alliance/inter_robot_communication"


def test_a_sample_counts_by_its_own_stamp_not_by_when_the_recorder_heard_it():
    """Window [0, 2): an odometry sent at 1.98 but heard at 2.06 (the recorder's clock ran
    ahead) counts; ones sent at 2.0 and 2.02 but heard at 1.96 and 1.99 (the recorder lagged)
    do not."""
    records = [rec("robot1/odom", odom("robot1", 0.5), 0.5),
               rec("robot1/odom", odom("robot1", 1.98), 2.06),
               rec("robot2/odom", odom("robot2", 2.0), 1.96),
               rec("robot2/odom", odom("robot2", 2.02), 1.99),
               rec(IRC, irc("robot1", 1.0), 1.0)]
    rates = message_rates(records, ALLIANCE, 2.0, lambda t: t / S)
    assert rates.total == 3 and rates.coordination_per_second == 0.5


def test_a_headerless_command_counts_by_its_agents_next_stamped_sample():
    """robot1's Twists: one followed by its broadcast of 1.9 (counts), one followed by its
    broadcast of 2.0 (the window's end: does not), and the zero velocity it sends as it stops,
    after which it says nothing (does not, whether or not the recorder caught it). The log
    times say otherwise each time."""
    records = [rec("robot1/cmd_vel", Twist(0.3, 0.0), 2.5),
               rec(IRC, irc("robot1", 1.9), 2.5),
               rec("robot1/cmd_vel", Twist(0.3, 0.1), 1.5),
               rec(IRC, irc("robot1", 2.0), 2.5),
               rec("robot1/cmd_vel", Twist(0.0, 0.0), 1.9)]
    rates = message_rates(records, ALLIANCE, 2.0, lambda t: t / S)
    assert rates.total == 2  # the first Twist and the broadcast of 1.9
    assert rates.coordination_per_second == 0.5


def test_without_log_times_every_sample_counts():
    records = [rec("robot1/cmd_vel", Twist(0.0, 0.0), 9.0), rec(IRC, irc("robot1", 5.0), 9.0)]
    assert message_rates(records, ALLIANCE, 2.0).total == 2


BURN = "import time\nend = time.monotonic() + 600\nwhile time.monotonic() < end:\n    pass\n"


@pytest.mark.multiprocess
@pytest.mark.slow
@pytest.mark.timeout(900)
def test_one_seed_twice_beside_two_cpu_burners_gives_one_summary(children, tmp_path):
    """The same seed run twice at --speed 0 with two processes burning both cores: the whole
    summary, bar the wall time and the output folder, is the same."""
    burners = [subprocess.Popen([sys.executable, "-c", BURN]) for _ in range(2)]
    try:
        summaries = []
        for i in range(2):
            summary = children.demo(tmp_path / f"run{i}", "--duration", "10", "--seed", "7",
                                    name=f"demo{i}").summary(300)
            for varying in ("wall_seconds", "output"):
                summary.pop(varying)
            summaries.append(summary)
    finally:
        for b in burners:
            b.kill()
            b.wait()
    assert summaries[0]["messages"]["total"] > 500
    assert summaries[0] == summaries[1]
