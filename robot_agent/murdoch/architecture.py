"""MURDOCH (Gerkey & Matarić 2002) as tools and the agent runtime see it: the object registered
under `mrta.architectures` as `murdoch`.

Who is doing what is read from the robots' own claims (a winner claims at once and renews every
renewal_period; docs/murdoch.md) and releases.
"""

from __future__ import annotations

from pathlib import Path

from mrta_zenoh.architectures import Doing
from mrta_zenoh.clock import Clock

from ..runtime.architecture import AgentArchitecture, Prepared
from ..runtime.host import AgentOptions
from ..runtime.plugins import Plugins
from . import params as murdoch_params
from .agent import MurdochCoordinator
from .messages import Announcement, Award, Bid, Claim, Release


def murdoch_plugins(params: murdoch_params.MurdochParams) -> Plugins:
    """Sensors, one progress evaluator and one layer stack per skill."""
    return Plugins(params.robot.sensors, params.evaluators(), params.task_layers(), params.layers)


SUBJECT_KINDS = ("announcement", "bid")  # published under a sub-key (agent.subjects)


class Murdoch(AgentArchitecture):
    name = "murdoch"
    title = "MURDOCH"
    namespace = "murdoch"
    executable = "murdoch/agent"
    command = "murdoch"
    param_stem = "murdoch"
    bound_formula = "lease + bid window + 3 ticks"
    messages = {"announcement": Announcement, "bid": Bid, "award": Award, "claim": Claim,
                "release": Release}
    doing_kinds = ("claim", "release")
    doing_stale_after = 2.0  # claims renewed every renewal_period (≤ the lease, 2 s by default)
    logger_name = "mrta.murdoch"

    def has_subkeys(self, kind: str) -> bool:
        """Announcements go out on their task's subject (`robot1/murdoch/announcement/t3`),
        bids to their auctioneer (`robot2/murdoch/bid/robot1`)."""
        return kind in SUBJECT_KINDS

    def prepare(self, options: AgentOptions) -> Prepared:
        params = murdoch_params.load_params(options.robot_params, options.tasks_params,
                                            options.layers_params)
        plugins = murdoch_plugins(params)
        return Prepared(options.robot_id, params, plugins, params.robot.spin_rate,
                        params.robot.control_rate, f"MURDOCH, {len(params.robot.skills)} skills",
                        params.warnings + plugins.unread_warnings())

    def coordinator(self, prepared: Prepared, agent_clock: Clock) -> MurdochCoordinator:
        return MurdochCoordinator(prepared.robot_id, prepared.params, prepared.plugins)

    def doing(self, sender: str, key: str, message: object) -> Doing | None:
        if isinstance(message, Claim):
            return Doing(sender, message.task_id, True, message.header.stamp)
        if isinstance(message, Release):
            return Doing(sender, message.task_id, False, message.header.stamp)
        return None

    def takeover_bound(self, robot_params: Path, task: str) -> float:
        """lease + bid window + 3 ticks (params.takeover_bound); the same for every task."""
        robot, _ = murdoch_params.load_robot(robot_params)
        return murdoch_params.takeover_bound(robot)


MURDOCH = Murdoch()
