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

from mrta_zenoh.architectures import Decision, Takeover, TakeoverBound, declared_out

from ..runtime.architecture import Prepared
from ..route.messages import Progress, Queued
from ..route.own_route_arch import OwnRouteArchitecture
from ..route.executor import PluginReadings
from . import params as ssi_params
from .agent import SsiCoordinator
from .messages import Bid, Round


class SsiArchitecture(OwnRouteArchitecture):
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
    objective = "minsum"
    decision_kinds = ("round",)
    takes_submitted = True  # a task submitted at run time opens at the next round (auction.py)
    logger_name = "mrta.ssi"
    params = ssi_params

    def has_subkeys(self, kind: str) -> bool:
        """A bid goes to its auctioneer (`robot2/ssi/bid/robot1`), each queued task of a robot
        under its own key (`robot1/ssi/queued/t3`)."""
        return kind in ("bid", "queued")

    coordinator_class: type[SsiCoordinator] = SsiCoordinator  # TeSSI's builds on it

    def coordinator(self, prepared: Prepared) -> SsiCoordinator:
        return self.coordinator_class(prepared.robot_id, prepared.params,
                              PluginReadings(prepared.plugins, prepared.params.robot.pose_topic))

    def decision(self, sender: str, key: str, message: object) -> Decision | None:
        """A Round that carries an award: one decision, by the auctioneer that sent it, taking
        `Round.ms` (its slowest bid and the winner determination, wall time); a Round repeated
        until every robot answered it is the same decision (its round number names it). Every
        Round says whom the auctioneer leaves out (`Round.out`: a stall, a silence), counted
        as a decision or not."""
        if not isinstance(message, Round):
            return None
        return Decision(sender, message.header.stamp, message.ms, self.objective,
                        ident=message.round, counted=message.award >= 0,
                        out=declared_out(message.out))

    def takeover_check(self, t: Takeover) -> TakeoverBound:
        return TakeoverBound(None, t.failed_at, case=(
            f"{self.title} re-auctions a lost robot's tasks at once, but whoever wins one serves "
            "it in its path's order, which the auction chooses: no bound on when it is served"))


SSI = SsiArchitecture()
