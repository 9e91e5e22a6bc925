"""What the contract objects of SSI and CBBA share (robots serving their own routes,
mrta_agent.route.own_route): how a robot is prepared from its files, what the file check
reads, and who is doing what, read from the robots' `Progress` reports."""

from __future__ import annotations

from pathlib import Path
from types import ModuleType
from typing import ClassVar

from ..runtime.architecture import Prepared
from ..runtime.host import AgentOptions
from ..runtime.plugins import Plugins
from .architecture import RouteArchitecture
from .messages import Progress
from .own_route_params import load_files


class OwnRouteArchitecture(RouteArchitecture):
    """Subclasses set `params` (the module with `load_params`, `load_robot`, WHAT and KEYS —
    the Struct of the architecture's own robot-file keys) besides the contract's attributes."""

    params: ClassVar[ModuleType]
    progress_type = Progress

    def prepare(self, options: AgentOptions) -> Prepared:
        params = self.params.load_params(options.robot_id, options.robot_params,
                                         options.tasks_params, options.layers_params)
        return self.route_prepared(options.robot_id, params, params.instance)

    def _plugins(self, robot_params: Path, tasks_params: Path) -> Plugins:
        """The robot's plugins from its robot and tasks files alone (load_files): the instance
        they name is the application's, read when the robot starts."""
        robot, tasks = load_files(robot_params, tasks_params, self.params.WHAT, self.params.KEYS)
        return Plugins(robot.sensors, robot.evaluators, tasks, None)

    def check_files(self, robot_id: str, robot_params: Path, tasks_params: Path,
                    layers_params: Path | None = None) -> None:
        self._plugins(robot_params, tasks_params)

    def layer_sections(self, robot_id: str, robot_params: Path,
                       tasks_params: Path) -> frozenset[str]:
        return frozenset(name for name, _ in self._plugins(robot_params, tasks_params).sections)

    def takeover_bound(self, robot_params: Path, task: str) -> float:
        """How soon a crashed robot's task is open again at a teammate: its next tick after the
        token goes — not when it is won again or served."""
        return 1.0 / self.params.load_robot(robot_params).spin_rate
