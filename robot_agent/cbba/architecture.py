"""CBBA (docs/cbba.md) as tools and the agent runtime see it: the object registered under
`mrta.architectures` as `cbba` — bundle construction and consensus (Choi, Brunet & How 2009),
asynchronous over the bus, each robot serving its bundle's path.

Who is doing what is read from the robots' `Progress` reports (what each set off to, its whole
queue). No decision records: CBBA decides nowhere in particular (every robot's table is the
decision, and converges). Takeover bound: none — a lost robot's wins are reset at each teammate
at the tick after its token goes (or after `progress_timeout` without progress) and re-bid, but
whoever wins one serves it in its path's order (docs/cbba.md, "In execution").
"""

from __future__ import annotations

from pathlib import Path

from mrta_zenoh.architectures import Doing, Takeover, TakeoverBound
from mrta_zenoh.clock import Clock

from ..runtime.architecture import AgentArchitecture, Prepared
from ..runtime.host import AgentOptions
from ..runtime.own_route import Progress, Queued
from ..runtime.plugins import Plugins
from ..runtime.route import PluginReadings
from . import params as cbba_params
from .agent import CbbaCoordinator
from .messages import Bids


class CbbaArchitecture(AgentArchitecture):
    name = "cbba"
    title = "CBBA"
    namespace = "cbba"
    executable = "cbba/agent"
    command = "cbba"
    param_stem = "cbba"
    bound_formula = ("none: wins reset within a tick of the loss, then re-bid and served in "
                     "the winner's path order")
    messages = {"bids": Bids, "progress": Progress, "queued": Queued}
    coordination_kinds = ("bids", "progress")
    doing_kinds = ("progress",)
    doing_stale_after = 2.5  # a robot reports every report_period (1 s by default)
    objective = None  # it maximises discounted rewards, none of planning.schedule's objectives
    logger_name = "mrta.cbba"

    def has_subkeys(self, kind: str) -> bool:
        """Each queued task of a robot under its own key (`robot1/cbba/queued/t3`)."""
        return kind == "queued"

    def prepare(self, options: AgentOptions) -> Prepared:
        params = cbba_params.load_params(options.robot_id, options.robot_params,
                                         options.tasks_params, options.layers_params)
        plugins = Plugins(params.robot.sensors, params.robot.evaluators, params.tasks,
                          params.layers)
        return Prepared(options.robot_id, params, plugins, params.robot.spin_rate,
                        params.robot.control_rate,
                        f"CBBA, {len(params.robot.evaluators)} tasks it can serve",
                        params.warnings + plugins.unread_warnings())

    def coordinator(self, prepared: Prepared, agent_clock: Clock) -> CbbaCoordinator:
        return CbbaCoordinator(prepared.robot_id, prepared.params,
                               PluginReadings(prepared.plugins, prepared.params.robot.pose_topic))

    def doing(self, sender: str, key: str, message: object) -> Doing | None:
        if not isinstance(message, Progress):
            return None
        queue = tuple(message.queue)
        if message.task:
            return Doing(sender, message.task, True, message.header.stamp, queue)
        return Doing(sender, message.last, False, message.header.stamp, queue)

    def takeover_bound(self, robot_params: Path, task: str) -> float:
        """How soon a crashed robot's task is free again at a teammate: its next tick after
        the token goes — not when it is won again or served (module docstring)."""
        return 1.0 / cbba_params.load_robot(robot_params).spin_rate

    def takeover_check(self, t: Takeover) -> TakeoverBound:
        return TakeoverBound(None, t.failed_at, case=(
            "CBBA re-bids a lost robot's tasks at once, but whoever wins one serves it in its "
            "path's order, which the bundles choose: no bound on when it is served"))


CBBA = CbbaArchitecture()
