"""ALLIANCE's messages as ROS 2 topics (`mrta ros2 bridge --mirror`): InterRobotCommunication
and Motivation with the original alliance_msgs definitions (adrianohrl/alliance,
alliance_msgs/msg/*.msg), ported to ROS 2 the way ROS 2 ports ROS 1 messages — `Header`
becomes `std_msgs/Header` (no seq), `duration` becomes `builtin_interfaces/Duration`. The
original's field spelling `aplicable` is kept, so a ROS 2 tool reading the original definitions
reads ours. Our `active_since` (our addition, messages.py) is not part of them.
"""

from __future__ import annotations

import math

from mrta_zenoh.ros2.mirror import Mirror
from mrta_zenoh.ros2.names import BEST_EFFORT, RELIABLE, Qos

from .messages import InterRobotCommunication, Motivation

IRC = "alliance_msgs/msg/InterRobotCommunication"
MOTIVATION = "alliance_msgs/msg/Motivation"
DEFINITIONS = {
    IRC: "std_msgs/Header header\nstring task_id\nbuiltin_interfaces/Duration expected_duration\n",
    MOTIVATION: ("std_msgs/Header header\nstring task_id\nfloat64 impatience\nbool acquiescent\n"
                 "bool suppressed\nbool resetted\nbool aplicable\nfloat64 motivation\n"
                 "float64 threshold\nbool active\n"),
}


def _duration(types, seconds: float):
    sec = math.floor(seconds)
    return types.new("builtin_interfaces/msg/Duration", sec=int(sec),
                     nanosec=min(int(round((seconds - sec) * 1e9)), 999_999_999))


def irc_to_ros(types, msg: InterRobotCommunication):
    return types.new(IRC, header=types.header(msg.header.stamp, msg.header.frame_id),
                     task_id=msg.task_id,
                     expected_duration=_duration(types, msg.expected_duration))


def motivation_to_ros(types, msg: Motivation):
    return types.new(MOTIVATION, header=types.header(msg.header.stamp, msg.header.frame_id),
                     task_id=msg.task_id, impatience=msg.impatience, acquiescent=msg.acquiescent,
                     suppressed=msg.suppressed, resetted=msg.resetted, aplicable=msg.applicable,
                     motivation=msg.motivation, threshold=msg.threshold, active=msg.active)


MIRRORS = [
    Mirror("alliance/inter_robot_communication", InterRobotCommunication, IRC,
           Qos(RELIABLE, depth=10), irc_to_ros, DEFINITIONS),
    Mirror("alliance/motivation/*", Motivation, MOTIVATION, Qos(BEST_EFFORT, depth=10),
           motivation_to_ros, DEFINITIONS),
]
