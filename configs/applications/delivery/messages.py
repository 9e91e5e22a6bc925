"""delivery_msgs: what a robot tells its team about a task it serves."""

from __future__ import annotations

from typing import Literal

from mrta_zenoh.messages import Header, Message, message


@message("delivery_msgs/TaskEvent")
class TaskEvent(Message):
    """`robotN/delivery/started` when the robot reaches the task and begins its service;
    `robotN/delivery/done` when the service is over. `done` is what makes the task
    inapplicable for every teammate (evaluators.TaskOpen), so it is sent reliably."""

    header: Header
    task_id: str
    event: Literal["started", "done"]
