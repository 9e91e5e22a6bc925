"""SSI (docs/ssi.md) as tools and the agent runtime see it: the object registered under
`mrta.architectures` as `ssi` — sequential single-item auctions cleared by the lowest-id live
robot, each robot serving the path its awards built.

Who is doing what is read from the robots' `Progress` reports (what each set off to, its whole
queue); every award is a decision (the auctioneer's `Round` carrying one). Takeover bound: none —
a lost robot's tasks are open again at the auctioneer's next tick after its token goes (or after
`progress_timeout` without progress), and awarded within a round per task, but whoever wins one
serves it in its path's order, which the auction chooses (docs/ssi.md, "In execution").
"""

from __future__ import annotations

from pathlib import Path

from mrta_zenoh.architectures import Decision, Doing, Takeover, TakeoverBound
from mrta_zenoh.clock import Clock

from ..runtime.architecture import AgentArchitecture, Prepared
from ..runtime.host import AgentOptions
from ..runtime.own_route import Progress, Queued
from ..runtime.plugins import Plugins
from ..runtime.route import PluginReadings
from . import params as ssi_params
from .agent import SsiCoordinator
from .messages import Bid, Round


class SsiArchitecture(AgentArchitecture):
    name = "ssi"
    title = "SSI"
    namespace = "ssi"
    executable = "ssi/agent"
    command = "ssi"
    param_stem = "ssi"
    bound_formula = ("none: re-opened within a tick of the loss, then served in the winner's "
                     "path order")
    messages = {"round": Round, "bid": Bid, "progress": Progress, "queued": Queued}
    coordination_kinds = ("round", "bid", "progress")
    doing_kinds = ("progress",)
    doing_stale_after = 2.5  # a robot reports every report_period (1 s by default)
    objective = "minsum"
    decision_kinds = ("round",)
    logger_name = "mrta.ssi"

    def has_subkeys(self, kind: str) -> bool:
        """A bid goes to its auctioneer (`robot2/ssi/bid/robot1`), each queued task of a robot
        under its own key (`robot1/ssi/queued/t3`)."""
        return kind in ("bid", "queued")

    def prepare(self, options: AgentOptions) -> Prepared:
        params = ssi_params.load_params(options.robot_id, options.robot_params,
                                        options.tasks_params, options.layers_params)
        plugins = Plugins(params.robot.sensors, params.robot.evaluators, params.tasks,
                          params.layers)
        return Prepared(options.robot_id, params, plugins, params.robot.spin_rate,
                        params.robot.control_rate,
                        f"SSI, {len(params.robot.evaluators)} tasks it can serve",
                        params.warnings + plugins.unread_warnings())

    def coordinator(self, prepared: Prepared, agent_clock: Clock) -> SsiCoordinator:
        return SsiCoordinator(prepared.robot_id, prepared.params,
                              PluginReadings(prepared.plugins, prepared.params.robot.pose_topic))

    def doing(self, sender: str, key: str, message: object) -> Doing | None:
        if not isinstance(message, Progress):
            return None
        queue = tuple(message.queue)
        if message.task:
            return Doing(sender, message.task, True, message.header.stamp, queue)
        return Doing(sender, message.last, False, message.header.stamp, queue)

    def decision(self, sender: str, key: str, message: object) -> Decision | None:
        """A Round that carries an award: one decision, by the auctioneer that sent it."""
        if not isinstance(message, Round) or message.award < 0:
            return None
        return Decision(sender, message.header.stamp, 0.0, self.objective)

    def takeover_bound(self, robot_params: Path, task: str) -> float:
        """How soon a crashed robot's task is open again: the auctioneer's next tick after the
        token goes — not when it is awarded or served (module docstring)."""
        return 1.0 / ssi_params.load_robot(robot_params).spin_rate

    def takeover_check(self, t: Takeover) -> TakeoverBound:
        return TakeoverBound(None, t.failed_at, case=(
            "SSI re-auctions a lost robot's tasks at once, but whoever wins one serves it in "
            "its path's order, which the auction chooses: no bound on when it is served"))


SSI = SsiArchitecture()
