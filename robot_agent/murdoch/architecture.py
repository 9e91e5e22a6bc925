"""MURDOCH (Gerkey & Matarić 2002) as tools and the agent runtime see it: the object registered
under `mrta.architectures` as `murdoch`.

Who is doing what is read from the robots' own claims (a winner claims at once and renews every
renewal_period; docs/murdoch.md) and releases.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

from mrta_zenoh import instances
from mrta_zenoh.architectures import Doing, Takeover, TakeoverBound
from mrta_zenoh.codec import DecodeError, decode, type_from_encoding

from ..runtime.architecture import AgentArchitecture, Prepared
from ..runtime.host import AgentOptions
from ..runtime.plugins import Plugins
from . import params as murdoch_params
from .agent import MurdochCoordinator
from .messages import Announcement, Award, Bid, Claim, Release, Revoke


def murdoch_plugins(params: murdoch_params.MurdochParams) -> Plugins:
    """Sensors, one progress evaluator and one layer stack per skill."""
    return Plugins(params.robot.sensors, params.evaluators(), params.task_layers(), params.layers)


def located(params: murdoch_params.MurdochParams, instance: instances.Loaded | None
            ) -> murdoch_params.MurdochParams:
    """A task its tasks file gives no `locations` is done where the robot's instance places it
    (InstanceKind.task_positions), so a package derived from an instance states its tasks'
    positions once — in the instance — and MURDOCH still prices its bids by distance."""
    where = {} if instance is None else instance.kind.task_positions(instance.doc)
    tasks = {tid: dataclasses.replace(t, locations=(where[tid],))
             if not t.locations and tid in where else t for tid, t in params.tasks.items()}
    return dataclasses.replace(params, tasks=tasks)


SUBJECT_KINDS = ("announcement", "bid")  # published under a sub-key (agent.subjects)


class MurdochArchitecture(AgentArchitecture):
    name = "murdoch"
    title = "MURDOCH"
    namespace = "murdoch"
    executable = "murdoch/agent"
    command = "murdoch"
    param_stem = "murdoch"
    bound_formula = "lease + bid window + 3 ticks + 2 × delay"
    messages = {"announcement": Announcement, "bid": Bid, "award": Award, "claim": Claim,
                "release": Release, "revoke": Revoke}
    doing_kinds = ("claim", "release")
    doing_stale_after = 2.0  # claims renewed every renewal_period (≤ the lease, 2 s by default)
    logger_name = "mrta.murdoch"

    def submitted_refusal(self) -> str:
        """MURDOCH grows no task at run time (takes_submitted False; docs/tasks.md)."""
        return ("MURDOCH serves no task submitted at run time: a robot's skills — the tasks its "
                "file lists, each a subscription and a liveliness token the auctioneer is "
                "ranked by — are declared at start-up (docs/tasks.md)")

    def has_subkeys(self, kind: str) -> bool:
        """Announcements go out on their task's subject (`robot1/murdoch/announcement/t3`),
        bids to their auctioneer (`robot2/murdoch/bid/robot1`)."""
        return kind in SUBJECT_KINDS

    def prepare(self, options: AgentOptions) -> Prepared:
        params = murdoch_params.load_params(options.robot_params, options.tasks_params,
                                            options.layers_params)
        plugins = murdoch_plugins(params)
        params = located(params, plugins.instance)
        return Prepared(options.robot_id, params, plugins, params.robot.spin_rate,
                        params.robot.control_rate, f"MURDOCH, {len(params.robot.skills)} skills",
                        params.warnings + plugins.unread_warnings())

    def coordinator(self, prepared: Prepared) -> MurdochCoordinator:
        return MurdochCoordinator(prepared.robot_id, prepared.params, prepared.plugins)

    def doing(self, sender: str, key: str, message: object) -> Doing | None:
        if isinstance(message, Claim):
            return Doing(sender, message.task_id, True, message.header.stamp)
        if isinstance(message, Release):
            return Doing(sender, message.task_id, False, message.header.stamp)
        return None

    def takeover_bound(self, robot_params: Path, task: str) -> float:
        """lease + bid window + 3 ticks (params.takeover_bound): the bound with no delivery
        delay; the same for every task. `takeover_check` adds the delay term and its
        condition."""
        robot, _ = murdoch_params.load_robot(robot_params)
        return murdoch_params.takeover_bound(robot)

    def takeover_check(self, t: Takeover) -> TakeoverBound:
        """params.takeover_bound with the run's largest delivery delay D, from the fault: in
        lockstep the latency the run injected (its mean + jitter), out of lockstep that plus
        the largest delay the recorder saw on MURDOCH's messages. It holds only while
        2·D + a tick < the bid window — a bid heard after its window closes is dropped and the
        task waits a reannounce_period for another auction — and with no loss, for the same
        reason (docs/murdoch.md, "Timing and the takeover bound")."""
        robot, _ = murdoch_params.load_robot(t.robot_params)
        delay = t.faults.latency[0] + t.faults.latency[1] if t.faults.latency else 0.0
        seen = "" if t.lockstep else " (as the recorder saw it)"
        if not t.lockstep:
            delay += self.observed_delay(t)
        tick, window = 1.0 / robot.spin_rate, robot.bid_window
        if t.faults.loss > 0:
            return TakeoverBound(None, t.failed_at, case=(
                f"with loss {t.faults.loss:g}: a lost announcement, bid or award costs a "
                "reannounce_period"))
        case = (f"for a largest delivery delay of {delay:.2f} s{seen}: 2 × delay + a tick = "
                f"{2 * delay + tick:.2f} s")
        if not murdoch_params.bids_in_time(robot, delay):
            return TakeoverBound(None, t.failed_at, case=(
                f"{case} ≥ the bid window {window:.2f} s: a bid may be heard after its window, "
                "and another auction starts"))
        return TakeoverBound(murdoch_params.takeover_bound(robot, delay), t.failed_at,
                             case=f"{case} < the bid window {window:.2f} s")

    def observed_delay(self, t: Takeover) -> float:
        """The largest (reception by the recorder − stamp) over MURDOCH's messages."""
        worst = 0.0
        for key, enc, logged, payload in t.records:
            if not self.is_coordination_key(key):
                continue
            try:
                msg = decode(type_from_encoding(enc), payload)
            except DecodeError:
                continue
            worst = max(worst, t.time_of(logged) - msg.header.stamp)
        return worst


MURDOCH = MurdochArchitecture()
