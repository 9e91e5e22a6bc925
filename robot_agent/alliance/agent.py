"""One robot's ALLIANCE agent: the high level and the low level in one process, on one clock.

The loop is single-threaded and scheduled on the injected clock, so it runs identically in real
time, under the simulator's clock at k× speed, and step by step in tests. Network callbacks
only enqueue; the loop thread owns all ALLIANCE state.
"""

from __future__ import annotations

import collections
import logging

import numpy as np

from mrta_zenoh.bus import Bus, Sample
from mrta_zenoh.clock import Clock
from mrta_zenoh.keys import first_chunk
from mrta_zenoh.messages import Header

from . import keys
from .high_level import HighLevel, TaskSwitch
from .messages import InterRobotCommunication, Motivation, SensoryFeedback
from .params import AgentParams
from ..runtime.loop import AgentLoop
from ..runtime.plugins import Plugins

log = logging.getLogger("mrta.agent")


class Agent(AgentLoop):
    def __init__(self, robot_id: str, params: AgentParams, bus: Bus, clock: Clock,
                 rng: np.random.Generator | None = None, plugins: Plugins | None = None):
        super().__init__(robot_id, bus, clock, rng,
                         plugins if plugins is not None else Plugins.for_alliance(params),
                         params.robot.spin_rate, params.robot.control_rate, log)
        self.params = params
        self.high = HighLevel(self.robot_id, params.robot)
        self.ignored_own = 0
        self.ignored_mismatch = 0
        self.ignored_strangers = 0  # broadcasts from robots with no live agent token
        self.refused = 0
        self._teammates: set[str] = set()
        self.transitions: list[tuple[float, TaskSwitch]] = []
        self._seq: dict[str, int] = collections.defaultdict(int)
        self._last_broadcast: float | None = None
        self._token = None
        self._irc_sub = None

    # ------------------------------------------------------------ set-up
    def start(self) -> None:
        """py_trees' setup: plugins subscribe, then the agent listens to its teammates."""
        self.plugins.setup(self.ctx)
        self._irc_sub = self.bus.subscribe(keys.ALL_INTER_ROBOT_COMMUNICATION, self._on_irc,
                                           msg_type=InterRobotCommunication)
        self._team_watch = self.bus.watch_liveliness(keys.ALL_AGENT_TOKENS, self._on_teammate)

    def _on_teammate(self, key: str, alive: bool) -> None:
        """Teammates are robots whose ALLIANCE agent holds its token; a broadcast from anyone
        else (a forged robot9) is ignored."""
        robot = first_chunk(key)
        if alive:
            self._teammates.add(robot)
        else:
            self._teammates.discard(robot)

    def declare_alive(self) -> None:
        """Last step of start-up: alive means ready (docs/zenoh.md, the start-up race)."""
        self._token = self.bus.declare_token(keys.agent_token(self.robot_id))

    def _on_irc(self, sample: Sample) -> None:
        sender = first_chunk(sample.key)
        if sender == self.robot_id:
            self.ignored_own += 1
            return
        if sample.message.header.frame_id.strip("/") != sender:
            self._drop("ignored_mismatch", "ignoring InterRobotCommunication on %s with frame_id %r",
                       sample.key, sample.message.header.frame_id)
            return
        if sender not in self._teammates:
            self._drop("ignored_strangers", "ignoring broadcasts from %s, which holds no agent token",
                       sender)
            return
        msg = sample.message
        self.heard(msg.header.stamp, sender, msg)

    # ------------------------------------------------------------ one step of each level
    def _header(self, key: str, now: float) -> Header:
        self._seq[key] += 1
        return Header(self.robot_id, now, self._seq[key])

    def tick_high(self, now: float) -> list[TaskSwitch]:
        for t, sender, msg in self.take_due(now):
            if not self.high.on_broadcast(sender, msg.task_id, msg.expected_duration, t,
                                          msg.active_since):
                self._drop("refused", "refused a broadcast from %s for %r with expected_duration %g",
                           sender, msg.task_id, msg.expected_duration)
        fb_key = keys.sensory_feedback(self.robot_id)
        for task, ev in self.plugins.evaluators.items():
            applicable = bool(ev.is_applicable(now))
            self.high.on_feedback(task, applicable, now)
            self.bus.publish(fb_key, SensoryFeedback(self._header(fb_key, now), task, applicable),
                             lossy=True)
        before = self.high.active_task
        states, transitions = self.high.tick(now)
        for st in states:
            key = keys.motivation(self.robot_id, st.task_id)
            self.bus.publish(key, Motivation(
                self._header(key, now), st.task_id, st.impatience, st.acquiescent, st.suppressed,
                st.resetted, st.applicable, st.motivation, st.threshold, st.active), lossy=True)
        for tr in transitions:
            self.transitions.append((now, tr))
            if tr.kind == "reset":
                log.info("%s: motivation for %s reset (%s) at t=%.2f", self.robot_id, tr.task_id,
                         tr.reason, now)
            else:
                log.info("%s: %s %s (%s) at t=%.2f", self.robot_id, tr.kind, tr.task_id,
                         tr.reason, now)
        after = self.high.active_task
        if self.switch_layers(before, after, now) and after is not None:
            self._last_broadcast = None  # announce a new activation at once
        self.maybe_broadcast(now)
        return transitions

    def maybe_broadcast(self, now: float) -> None:
        task = self.high.active_task
        if task is None:
            return
        period = 1.0 / self.params.robot.broadcast_rate
        if self._last_broadcast is not None and now - self._last_broadcast < period - 1e-9:
            return
        self._last_broadcast = now
        key = keys.inter_robot_communication(self.robot_id)
        self.bus.publish(key, InterRobotCommunication(
            self._header(key, now), task, self.high.sets[task].params.expected_duration,
            self.high.active_since()))

    @property
    def active_task(self) -> str | None:
        return self.high.active_task

    # ------------------------------------------------------------ the loop
    def restart(self, now: float) -> None:
        """Time restarted (a new simulation run): the old run's world is gone, so start afresh —
        layers deactivated, sensors forgotten, motivations back to zero."""
        self.reset_low_level(now)
        self.high = HighLevel(self.robot_id, self.params.robot)
        self._last_broadcast = None

    def shutdown(self) -> None:
        """Stop the robot: deactivate the running layers, command zero velocity, and let every
        plugin close what it opened (py_trees' terminate, then shutdown)."""
        self.shutdown_low_level()
        if self._irc_sub is not None:
            self._irc_sub.close()
            self._team_watch.close()
            self._irc_sub = None
