"""Mirrors: an architecture's own messages republished as ROS 2 topics, so ROS 2 tools see the
team's coordination (`mrta ros2 bridge --mirror`).

An architecture registers a list of Mirror under the `mrta.ros2.mirrors` entry-point group; the
core knows none of them (ALLIANCE registers InterRobotCommunication and Motivation with the
original alliance_msgs definitions, robot_agent/alliance/ros2.py).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Callable

from ..errors import ConfigError
from ..installed import entry_points
from .names import Qos

GROUP = "mrta.ros2.mirrors"


@dataclass(frozen=True)
class Mirror:
    """Samples on `robotN/<suffix>` (a key expression relative to the robot) of `our_type`
    become `ros_type` messages on the ROS 2 topic named like the key (`/robotN/<rest>` under the
    robot's namespace). `definitions` holds the .msg text of every type it needs beyond the
    distro's store; `convert(types, msg)` builds the ROS 2 message."""

    suffix: str
    our_type: type
    ros_type: str
    qos: Qos
    convert: Callable[[Any, Any], Any]
    definitions: dict[str, str] = field(default_factory=dict)


def registered_mirrors() -> list[Mirror]:
    out: list[Mirror] = []
    for ep in entry_points(group=GROUP):
        items = ep.load()
        if not isinstance(items, (list, tuple)) or not all(isinstance(m, Mirror) for m in items):
            raise ConfigError(f"entry point {ep.name!r} ({ep.value}) in {GROUP} is not a list "
                              "of Mirror")
        out.extend(items)
    return out


def definitions(mirrors: list[Mirror]) -> dict[str, str]:
    out: dict[str, str] = {}
    for m in mirrors:
        out.update(m.definitions)
    return out
