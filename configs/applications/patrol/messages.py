"""patrol_msgs: the team report the `report` layer publishes."""

from __future__ import annotations

from mrta_zenoh.messages import Finite, Header, Message, message


@message("patrol_msgs/TaskTime")
class TaskTime(Message):
    robot_id: str
    task_id: str
    seconds: Finite


@message("patrol_msgs/Report")
class Report(Message):
    header: Header
    distance: Finite         # metres covered by the whole team
    border_covered: Finite   # share of the border's 0.5 m cells some robot came near
    task_times: tuple[TaskTime, ...]
