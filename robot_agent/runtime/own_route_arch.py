"""What the contract objects of SSI and CBBA share (robots serving their own routes,
mrta_agent.runtime.own_route): how a robot is prepared from its files, what the file check
reads, and who is doing what, read from the robots' `Progress` reports."""

from __future__ import annotations

from pathlib import Path
from types import ModuleType
from typing import ClassVar

from mrta_zenoh.architectures import Doing

from .architecture import AgentArchitecture, Prepared
from .host import AgentOptions
from .own_route import Progress
from .own_route_params import load_files
from .plugins import Plugins


class OwnRouteArchitecture(AgentArchitecture):
    """Subclasses set `params` (the module with `load_params`, `load_robot`, WHAT, KEYS and
    `_read`) besides the contract's attributes."""

    params: ClassVar[ModuleType]
    doing_kinds = ("progress",)
    doing_stale_after = 2.5  # a robot reports every report_period (1 s by default)

    def prepare(self, options: AgentOptions) -> Prepared:
        params = self.params.load_params(options.robot_id, options.robot_params,
                                         options.tasks_params, options.layers_params)
        plugins = Plugins(params.robot.sensors, params.robot.evaluators, params.tasks,
                          params.layers)
        return Prepared(options.robot_id, params, plugins, params.robot.spin_rate,
                        params.robot.control_rate,
                        f"{self.title}, {len(params.robot.evaluators)} tasks it can serve",
                        params.warnings + plugins.unread_warnings())

    def _plugins(self, robot_params: Path, tasks_params: Path) -> Plugins:
        """The robot's plugins from its robot and tasks files alone (load_files): the instance
        they name is the application's, read when the robot starts."""
        robot, tasks = load_files(robot_params, tasks_params, self.params.WHAT,
                                  self.params.KEYS, self.params.read_keys)
        return Plugins(robot.sensors, robot.evaluators, tasks, None)

    def check_files(self, robot_id: str, robot_params: Path, tasks_params: Path,
                    layers_params: Path | None = None) -> None:
        self._plugins(robot_params, tasks_params)

    def layer_sections(self, robot_id: str, robot_params: Path,
                       tasks_params: Path) -> frozenset[str]:
        return frozenset(name for name, _ in self._plugins(robot_params, tasks_params).sections)

    def doing(self, sender: str, key: str, message: object) -> Doing | None:
        if not isinstance(message, Progress):
            return None
        queue = tuple(message.queue)
        if message.task:
            return Doing(sender, message.task, True, message.header.stamp, queue)
        return Doing(sender, message.last, False, message.header.stamp, queue)

    def takeover_bound(self, robot_params: Path, task: str) -> float:
        """How soon a crashed robot's task is open again at a teammate: its next tick after the
        token goes — not when it is won again or served."""
        return 1.0 / self.params.load_robot(robot_params).spin_rate
