"""What the supervisor holds per robot and per task."""

from __future__ import annotations

from dataclasses import dataclass, field

from .holders import SampleHolder


@dataclass
class RobotInfo:
    id: str
    known: bool                 # part of the application
    busy: SampleHolder
    idle: SampleHolder
    tokens: set[str] = field(default_factory=set)
    ever_token: bool = False
    bridges: set[str] = field(default_factory=set)  # `@mrta/ros2_bridge/<id>` tokens alive
    ros2_driver: bool = False   # a ROS 2 node lives in the robot's namespace
    ever_ros2: bool = False     # … and one did since a bridge took the robot
    state: str = "offline"
    since: float = 0.0


@dataclass
class TaskInfo:
    id: str
    known: bool
    incoming: SampleHolder
    state: str = "unallocated"
    robots: tuple[str, ...] = ()
    since: float = 0.0
    # what the application said of the task (supervisor/tasks.py): "done" or "waiting", up to
    # `until` (None: for good); a task that is neither needs a robot
    status: str | None = None
    until: float | None = None
