"""One robot's MURDOCH agent: the auction logic (auction.Murdoch) and the robot's low level in
one process, on one clock — the same loop, hosting and plugins as the ALLIANCE agent
(robot_agent.runtime, mrta_agent.runtime.plugins), so the patrol layers run here unchanged.

Network callbacks only enqueue; the loop thread owns all state. In lockstep every robot shares
one simulated time, so a message's own stamp is when it was heard, whatever the network did.
"""

from __future__ import annotations

import collections
import logging
import math

import numpy as np

from mrta_zenoh.bus import Bus, Sample
from mrta_zenoh.clock import Clock
from mrta_zenoh.keys import first_chunk
from mrta_zenoh.messages import Header, Odometry
from mrta_agent.runtime.plugins import Plugins
from mrta_agent.runtime.loop import AgentLoop

from . import keys
from .auction import Change, Murdoch
from .messages import Announcement, Award, Bid, Claim, Release
from .params import MurdochParams

log = logging.getLogger("mrta.murdoch")

MESSAGES = {"announcement": Announcement, "bid": Bid, "award": Award, "claim": Claim,
            "release": Release}  # keys.KINDS → type; heard by Murdoch.on_<kind>


def plugins_for(params: MurdochParams) -> Plugins:
    """Sensors, one progress evaluator and one layer stack per skill."""
    return Plugins(params.robot.sensors, params.evaluators(), params.task_layers(), params.layers)


class _Readings:
    """What auction.Murdoch asks of the robot, answered from its plugins."""

    def __init__(self, plugins: Plugins, pose_topic: str | None):
        self.plugins = plugins
        self.pose_topic = pose_topic

    def fresh(self, topic: str, now: float) -> bool:
        sensor = self.plugins.sensors.get(topic)
        return sensor is not None and sensor.is_up_to_date(now)

    def applicable(self, task_id: str, now: float) -> bool:
        ev = self.plugins.evaluators.get(task_id)
        return ev is not None and bool(ev.is_applicable(now))

    def pose(self) -> tuple[float, float] | None:
        sensor = self.plugins.sensors.get(self.pose_topic) if self.pose_topic else None
        msg = sensor.latest if sensor is not None else None
        return (msg.pose.x, msg.pose.y) if isinstance(msg, Odometry) else None


class MurdochAgent(AgentLoop):
    def __init__(self, robot_id: str, params: MurdochParams, bus: Bus, clock: Clock,
                 rng: np.random.Generator | None = None, plugins: Plugins | None = None):
        super().__init__(robot_id, bus, clock, rng,
                         plugins if plugins is not None else plugins_for(params),
                         params.robot.spin_rate, params.robot.control_rate, log)
        self.params = params
        self.readings = _Readings(self.plugins, params.robot.pose_topic)
        self.core = Murdoch(self.robot_id, params.robot, params.tasks)
        self._seq: dict[str, int] = collections.defaultdict(int)
        self.changes: list[tuple[float, Change]] = []
        self.ignored_mismatch = 0
        self.ignored_strangers = 0
        self._handles: list = []
        self._token = None

    # ------------------------------------------------------------ set-up
    def start(self) -> None:
        self.plugins.setup(self.ctx)
        for kind, cls in MESSAGES.items():
            self._handles.append(self.bus.subscribe(
                keys.every(kind), lambda s, h="on_" + kind: self._on_message(h, s), msg_type=cls))
        self._handles.append(self.bus.watch_liveliness(keys.ALL_AGENT_TOKENS, self._on_teammate))

    def declare_alive(self) -> None:
        self._token = self.bus.declare_token(keys.of(self.robot_id, "agent"))

    def _on_teammate(self, key: str, alive: bool) -> None:
        """Queued like the messages, always due: the loop thread owns the team too."""
        self._inbox.append((-math.inf, "teammate", first_chunk(key), alive))

    def _on_message(self, handler: str, sample: Sample) -> None:
        sender = first_chunk(sample.key)
        msg = sample.message
        if sender == self.robot_id:
            return
        if msg.header.frame_id.strip("/") != sender:
            self._drop("ignored_mismatch", "ignoring %s on %s with frame_id %r",
                       type(msg).__name__, sample.key, msg.header.frame_id)
            return
        self.heard(msg.header.stamp, handler, sender, msg)

    # ------------------------------------------------------------ one step of each level
    def tick_high(self, now: float) -> list[Change]:
        for t, handler, sender, what in self.take_due(now):
            if handler == "teammate":
                if sender != self.robot_id:
                    self.core.on_teammate(sender, what)
                continue
            msg = what
            if sender not in self.core.teammates:
                self._drop("ignored_strangers", "ignoring %s from %s, which holds no agent token",
                           type(msg).__name__, sender)
                continue
            getattr(self.core, handler)(sender, msg, t)
        before = self.core.task
        out, changes = self.core.tick(now, self.readings)
        for kind, fields in out:
            key = keys.of(self.robot_id, kind)
            self._seq[key] += 1
            self.bus.publish(key, MESSAGES[kind](Header(self.robot_id, now, self._seq[key]),
                                                 *fields))
        for change in changes:
            self.changes.append((now, change))
            log.info("%s: %s %s (%s) at t=%.2f", self.robot_id, change.kind, change.task_id,
                     change.reason, now)
        self.switch_layers(before, self.core.task, now)
        return changes

    @property
    def active_task(self) -> str | None:
        return self.core.task

    def restart(self, now: float) -> None:
        """Time restarted (a new simulation run): forget every lease, auction and sensor."""
        self.reset_low_level(now)
        teammates = self.core.teammates
        self.core = Murdoch(self.robot_id, self.params.robot, self.params.tasks)
        self.core.teammates = set(teammates)

    def shutdown(self) -> None:
        self.shutdown_low_level()
        for h in self._handles:
            h.close()
        self._handles.clear()
