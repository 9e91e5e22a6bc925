"""ALLIANCE (Parker 1998) as tools and the agent runtime see it: the object registered under
`mrta.architectures` as `alliance`.

Who is doing what is read from each robot's own Motivation samples (`active`, one per behaviour
set per tick, stamped with the robot's clock) — what the robot decided, exact to one tick —
rather than from its broadcasts (1 Hz, and only while active) or a supervisor's timeout.
"""

from __future__ import annotations

import math
from pathlib import Path

from mrta_zenoh.architectures import Doing, Takeover, TakeoverBound
from mrta_zenoh.codec import DecodeError, decode
from mrta_zenoh.errors import ConfigError
from mrta_zenoh.failure import plan_for
from mrta_zenoh.keys import first_chunk
from mrta_zenoh.yamlfile import plural

from ..runtime.architecture import AgentArchitecture, Prepared
from ..runtime.host import AgentOptions
from ..runtime.plugins import EvaluatorSpec, Plugins
from .agent import AllianceCoordinator
from .high_level import exact
from .messages import InterRobotCommunication, Motivation, SensoryFeedback
from .params import AgentParams, load_agent_params, load_robot_params


def alliance_plugins(params: AgentParams) -> Plugins:
    """One evaluator and one layer stack per behaviour set."""
    return Plugins(params.robot.sensors,
                   [EvaluatorSpec(bs.task_id, bs.evaluator_plugin, bs.evaluator_topics, bs.where)
                    for bs in params.robot.behaviour_sets],
                   params.tasks, params.layers)


class AllianceArchitecture(AgentArchitecture):
    name = "alliance"
    title = "ALLIANCE"
    namespace = "alliance"
    executable = "robot_agent/agent"
    command = "agent"
    param_stem = "alliance"
    # from the taker's last reception of any broadcast on the task (takeover_check)
    bound_formula = "τ + (⌈θ/fast⌉ + 1)/ρ"
    messages = {"inter_robot_communication": InterRobotCommunication,
                "motivation": Motivation, "sensory_feedback": SensoryFeedback}
    # what robots tell each other is the broadcast alone (Parker's inter-robot communication);
    # Motivation and SensoryFeedback (one per behaviour set per tick) are rqt_alliance's
    # monitoring, read by no teammate
    coordination_kinds = ("inter_robot_communication",)
    doing_kinds = ("motivation",)
    doing_stale_after = 1.0  # Motivation every tick (spin_rate ≥ 1 Hz in every shipped file)

    def has_subkeys(self, kind: str) -> bool:
        return kind == "motivation"

    def submitted_refusal(self) -> str:
        """ALLIANCE grows no task at run time (takes_submitted False; docs/tasks.md)."""
        return ("ALLIANCE serves no task submitted at run time: a robot's behaviour sets, each "
                "with the motivation parameters its robot file gives for that task, are fixed "
                "at start-up (docs/tasks.md)")

    def prepare(self, options: AgentOptions) -> Prepared:
        params = load_agent_params(options.robot_params, options.tasks_params,
                                   options.layers_params)
        plugins = alliance_plugins(params)
        return Prepared(options.robot_id, params, plugins, params.robot.spin_rate,
                        params.robot.control_rate,
                        f"{plural(len(params.robot.behaviour_sets), 'behaviour set')}",
                        params.warnings + plugins.unread_warnings())

    def coordinator(self, prepared: Prepared) -> AllianceCoordinator:
        return AllianceCoordinator(prepared.robot_id, prepared.params, prepared.plugins)

    def doing(self, sender: str, key: str, message: object) -> Doing | None:
        if not isinstance(message, Motivation):
            return None
        return Doing(sender, message.task_id, message.active, message.header.stamp)

    def takeover_bound(self, robot_params: Path, task: str) -> float:
        """τ + ⌈θ / fast_rate⌉ / ρ + one tick: the longest a robot with these parameters
        takes to pick up `task` once it has stopped hearing about it — counted from its last
        reception of *any* broadcast on the task, from whichever robot (`takeover_check`).

        Why that instant: only a reception resets motivation or makes impatience slow, and a
        record stays fresh for τ after it; past that, impatience is fast_rate per tick from at
        least 0, so the set crosses θ within ⌈θ/fast_rate⌉ ticks of the first tick after. The
        dead robot's last broadcast is not enough: a survivor that missed it while still
        hearing a robot that had just yielded the task (the yielded robot broadcast until its
        yield) stays slow until τ after *that* robot's last broadcast. Conditions: the taker
        is idle, the task applicable to it, and no other of its sets crosses its threshold
        first. ⌈θ/fast_rate⌉ is exact (the decimals as written: θ=2.1, fast_rate=0.7 → 3
        ticks, where floats say 4), as the high level's motivation is."""
        robot, _ = load_robot_params(robot_params)
        for bs in robot.behaviour_sets:
            if bs.task_id == task:
                ticks = math.ceil(exact(bs.threshold) / exact(bs.fast_rate))
                return float(exact(robot.timeout_duration) + (ticks + 1) / exact(robot.spin_rate))
        raise ConfigError(f"no behaviour set for task {task!r}", file=str(robot_params))

    def takeover_check(self, t: Takeover) -> TakeoverBound:
        """`takeover_bound`, counted from the taker's last reception, before it took the task,
        of a broadcast on the task from any other robot. In lockstep a broadcast is heard at
        its stamp, plus the latency the run injected, unless the run's loss or a partition (the
        taker's, or the sender's: a cut-off robot's broadcasts are recorded, nobody hears them)
        took it — the driver's own seeded draws (mrta_zenoh.failure.FaultPlan), made again
        here — so the instant is exact. Out of lockstep the recorder's reception stands for
        the taker's (both on the same loopback). A taker that heard nobody: from the fault."""
        bound = self.takeover_bound(t.robot_params, t.task)
        plan = plan_for(t.faults, t.taker, t.seed)
        last: tuple[float, str] | None = None
        for key, _enc, logged, payload in t.records:
            sender = first_chunk(key)
            if sender == t.taker or key != self.key(sender, "inter_robot_communication"):
                continue
            try:
                msg = decode(InterRobotCommunication.TYPE_NAME, payload)
            except DecodeError:
                continue
            if msg.task_id != t.task or msg.header.frame_id.strip("/") != sender:
                continue
            seq = msg.header.seq
            if plan is not None and (plan.lost(key, seq)
                                     or plan.sender_cut(sender, msg.header.stamp)):
                continue
            heard = (msg.header.stamp if t.lockstep else t.time_of(logged)) \
                + (plan.delay(key, seq) if plan is not None else 0.0)
            if (plan is not None and plan.cut_off(heard)) or heard > t.taken_at:
                continue
            if last is None or heard > last[0]:
                last = (heard, sender)
        if last is None:
            return TakeoverBound(bound, t.failed_at, "", f"{t.taker} heard no broadcast on "
                                 f"{t.task}: counted from the fault")
        heard, sender = last
        how = "" if t.lockstep else " (by the recorder)"
        return TakeoverBound(bound, heard, f"{sender}'s broadcast heard at {heard:.2f} s{how}, "
                                           f"the last on {t.task} it heard")

    def plots(self, recording: Path, robots: list[str], tasks: list[str], output: Path,
              records: list | None = None) -> list[str]:
        """rqt_alliance's seven panels for each robot and task it was active on at some time
        (its behaviour set ran): the motivations that decided the run. Every pair was drawn
        before — 258 pictures (110 s, 31 MB) for the README's 20-robot instance, most of a
        motivation that never crossed its threshold; `mrta plot motivation` draws any pair."""
        from mrta_zenoh.recording import TimeBase, read_recording
        from .plots import draw_motivation, motivation_rows  # matplotlib: only for pictures
        records = list(read_recording(recording)) if records is None else records
        tb = TimeBase(records)
        rows = motivation_rows(records, tb)
        written = []
        for robot in robots:
            for task in tasks:
                mine = rows.get(self.key(robot, "motivation", task), [])
                if any(m.active for _, m in mine):
                    f = output / f"motivation_{robot}_{task}.png"
                    draw_motivation(mine, tb, robot, task, f)
                    written.append(f.name)
        return written


ALLIANCE = AllianceArchitecture()
