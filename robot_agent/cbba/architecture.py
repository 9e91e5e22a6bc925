"""CBBA (docs/cbba.md) as tools and the agent runtime see it: the object registered under
`mrta.architectures` as `cbba` — bundle construction and consensus (Choi, Brunet & How 2009),
asynchronous over the bus, each robot serving its bundle's path.

Who is doing what is read from the robots' `Progress` reports (what each set off to, its whole
queue). Decisions: CBBA decides nowhere in particular (every robot's table is the decision,
and converges), so a decision here is one robot's bundle work that changed its table — the
`Bids` it then sends carries its wall-time cost (`Bids.ms`); a resend of an unchanged table is
none. Takeover bound: none — a lost robot's wins are reset at each teammate
at the tick after its token goes (or after `progress_timeout` without progress) and re-bid, but
whoever wins one serves it in its path's order (docs/cbba.md, "In execution").
"""

from __future__ import annotations

from mrta_zenoh.architectures import Decision, Takeover, TakeoverBound, declared_out

from ..runtime.architecture import Prepared
from ..route.messages import Progress, Queued
from ..route.own_route_arch import OwnRouteArchitecture
from ..route.executor import PluginReadings
from . import params as cbba_params
from .agent import CbbaCoordinator
from .messages import Bids


class CbbaArchitecture(OwnRouteArchitecture):
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
    decision_kinds = ("bids",)
    objective = None  # it maximises discounted rewards, none of planning.schedule's objectives
    takes_submitted = True  # a new column of every robot's bid table (bundle.py, tasks_added)
    logger_name = "mrta.cbba"
    params = cbba_params

    def decision(self, sender: str, key: str, message: object) -> Decision | None:
        """A Bids that follows a change of its sender's table: one decision, by that robot,
        taking `Bids.ms` (its bundle work since its previous Bids, wall time); every Bids says
        whom its sender counts out (`Bids.out`, a stall), counted as a decision or not."""
        if not isinstance(message, Bids):
            return None
        return Decision(sender, message.header.stamp, message.ms, self.objective,
                        counted=message.ms > 0.0, out=declared_out(message.out))

    def has_subkeys(self, kind: str) -> bool:
        """Each queued task of a robot under its own key (`robot1/cbba/queued/t3`)."""
        return kind == "queued"

    def coordinator(self, prepared: Prepared) -> CbbaCoordinator:
        return CbbaCoordinator(prepared.robot_id, prepared.params,
                               PluginReadings(prepared.plugins, prepared.params.robot.pose_topic))


    def takeover_check(self, t: Takeover) -> TakeoverBound:
        return TakeoverBound(None, t.failed_at, case=(
            "CBBA re-bids a lost robot's tasks at once, but whoever wins one serves it in its "
            "path's order, which the bundles choose: no bound on when it is served"))


CBBA = CbbaArchitecture()
