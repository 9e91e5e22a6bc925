"""A delivery is counted from the robots' own `started` and `done` (issue 51): the analysis
believes them as the robots' boards do (done_rule.py) and, where the recording has the
simulator's ground truth, only where the robot really was (metrics.believed_events). The
boards' rule on the bus: tests/test_delivery.py; a forger on a real run's bus:
tests/process/test_coordination_attacks.py."""

from __future__ import annotations

import msgspec

from mrta_delivery.instance import InstanceBody
from mrta_delivery.messages import TaskEvent
from mrta_delivery.metrics import believed_events, done_at
from mrta_zenoh.codec import encode, encoding_for
from mrta_zenoh.messages import Header, Odometry, Pose2D, Twist

PARAMS = msgspec.convert({
    "robots": {"robot1": {"start": [0.0, 0.0], "speed": 1.0}},
    "tasks": {"t1": {"position": [5.0, 0.0], "service": 2.0}}}, InstanceBody)


def event(robot: str, kind: str, at: float) -> tuple:
    msg = TaskEvent(Header(robot, at, int(at * 10)), "t1", kind)
    return (f"{robot}/delivery/{kind}", encoding_for(TaskEvent.TYPE_NAME), int(at * 1e9),
            encode(msg))


def truth(robot: str, at: float, x: float) -> tuple:
    msg = Odometry(Header(robot, at, int(at * 10)), Pose2D(x, 0.0, 0.0), Twist(0.0, 0.0))
    return (f"{robot}/ground_truth", encoding_for(Odometry.TYPE_NAME), int(at * 1e9), encode(msg))


def recording(x_of) -> list:
    """robot1 says it started t1 at 6 and served it at 8; `x_of(t)`: where it really was."""
    out = [truth("robot1", t / 2, x_of(t / 2)) for t in range(0, 21)]
    out += [event("robot1", "started", 6.0), event("robot1", "done", 8.0)]
    return sorted(out, key=lambda r: r[2])


def test_a_done_said_where_the_robot_was_not_is_not_a_delivery():
    """A certified robot that says `started` and `done` in time without moving convinces its
    teammates (docs/security.md), but the ground truth has it at its start: not delivered."""
    still = recording(lambda t: 0.0)
    assert done_at(still, PARAMS) is None
    assert believed_events(still, PARAMS, 0.3) == ([], 2)


def test_a_done_said_at_the_task_is_a_delivery():
    moved = recording(lambda t: min(t, 5.0))
    assert done_at(moved, PARAMS) == 8.0
    assert believed_events(moved, PARAMS, 0.3)[1] == 0


def test_without_ground_truth_a_done_counts_after_its_started_only():
    """A real fleet's recording (no simulator): the boards' rule alone."""
    alone = [event("robot1", "done", 3.0)]
    assert done_at(alone, PARAMS) is None
    said = [event("robot1", "started", 6.0), event("robot1", "done", 8.0)]
    assert done_at(said, PARAMS) == 8.0
