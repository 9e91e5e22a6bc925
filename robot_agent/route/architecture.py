"""The contract of every architecture whose robots serve an ordered route of point tasks
(central, SSI, CBBA): how a robot is prepared from its route parameters, and who is doing what,
read from the robots' `Progress` reports."""

from __future__ import annotations

from typing import Any, ClassVar

from mrta_zenoh import instances
from mrta_zenoh.architectures import Doing

from ..runtime.architecture import AgentArchitecture, Prepared
from ..runtime.plugins import Plugins


class RouteArchitecture(AgentArchitecture):
    """An architecture whose robots serve an ordered route of point tasks (route.executor) and
    say so in a `progress_type` report — the task set off to, the last one served or left,
    the queue: central's and the own-route architectures (SSI, CBBA)."""

    progress_type: ClassVar[type]
    doing_kinds = ("progress",)
    doing_stale_after = 2.5  # a robot reports every report_period (1 s by default)
    continuous_tasks = False  # a route is of tasks that end (Architecture.continuous_tasks)

    def route_prepared(self, robot_id: str, params: Any,
                       instance: instances.Loaded | None = None) -> Prepared:
        """What `prepare` gives for parameters with `robot` (sensors, evaluators, rates),
        `tasks`, `layers` and `warnings`; `instance`: the robot's, when already read."""
        plugins = Plugins(params.robot.sensors, params.robot.evaluators, params.tasks,
                          params.layers, instance)
        return Prepared(robot_id, params, plugins, params.robot.spin_rate,
                        params.robot.control_rate,
                        f"{self.title}, {len(params.robot.evaluators)} tasks it can serve",
                        params.warnings + plugins.unread_warnings())

    def doing(self, sender: str, key: str, message: object) -> Doing | None:
        if not isinstance(message, self.progress_type):
            return None
        queue = tuple(message.queue)
        if getattr(message, "holding", False):
            # it stands still, its dispatcher silent past its lease: it serves nothing now, and
            # whoever the dispatcher gives its tasks meanwhile overlaps nobody (issue 51.2);
            # reporting again without holding, it holds its queue from then
            return Doing(sender, message.task or message.last, False, message.header.stamp, ())
        if message.task:
            return Doing(sender, message.task, True, message.header.stamp, queue)
        return Doing(sender, message.last, False, message.header.stamp, queue)
