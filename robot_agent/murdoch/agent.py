"""MURDOCH's decision logic for one robot, as the agent runtime drives it: the auction logic
(auction.Murdoch, pure logic on virtual time) with the robot's plugins as its readings — which
sensors are fresh, whether a task's progress evaluator holds, where the robot is.

The driver (mrta_agent.runtime.loop.Agent) owns the inbox, the team, sender checks, headers and
layers; this class only decides. In lockstep every robot shares one simulated time, so a
message's own stamp is when it was heard, whatever the network did.
"""

from __future__ import annotations

import collections
import logging
from typing import Iterable

from mrta_zenoh.messages import Odometry
from mrta_zenoh.timetext import at

from ..runtime.coordinator import Coordinator, Say
from ..runtime.plugins import Plugins
from .auction import Change, Murdoch
from .params import MurdochParams

log = logging.getLogger("mrta.murdoch")
HISTORY = 256  # decisions kept for inspection (tests, a debugger): bounded, a robot runs for days


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

    def done(self, task_id: str, now: float) -> bool:
        """Whether this robot finished the task since its layers were last activated."""
        return any(layer.done(now) for layer in self.plugins.layers.get(task_id, ()))

    def pose(self) -> tuple[float, float] | None:
        sensor = self.plugins.sensors.get(self.pose_topic) if self.pose_topic else None
        msg = sensor.latest if sensor is not None else None
        return (msg.pose.x, msg.pose.y) if isinstance(msg, Odometry) else None


class MurdochCoordinator(Coordinator):
    listens = ("announcement", "bid", "award", "claim", "release", "revoke")

    def __init__(self, robot_id: str, params: MurdochParams, plugins: Plugins):
        self.robot_id = robot_id
        self.params = params
        self.readings = _Readings(plugins, params.robot.pose_topic)
        self.core = Murdoch(robot_id, params.robot, params.tasks)
        self.history: collections.deque[tuple[float, Change]] = collections.deque(maxlen=HISTORY)

    @property
    def active_task(self) -> str | None:
        return self.core.task

    def teammate(self, robot: str, alive: bool) -> None:
        self.core.teammate(robot, alive)

    @property
    def advertises(self) -> tuple[str, ...]:
        """The tasks this robot serves, one liveliness token each (`robotN/murdoch/subject/<task>`,
        mrta_agent.runtime.loop): teammates rank a task's auctioneers among its servers."""
        return self.core.subjects

    def teammate_subject(self, robot: str, subject: str, alive: bool) -> None:
        self.core.teammate_subject(robot, subject, alive)

    def hear(self, kind: str, sender: str, msg, at: float) -> bool:
        return self.core.hear(kind, sender, msg, at)

    def refusals(self):
        """What the auction logic did not believe (its `refused`: a premature Revoke), with
        what this coordinator refused itself."""
        return collections.Counter(super().refusals()) + self.core.refused

    def tick(self, now: float) -> Iterable[Say]:
        out, changes = self.core.tick(now, self.readings)
        for change in changes:
            self.history.append((now, change))
            log.info("%s: %s %s (%s) %s", self.robot_id, change.kind, change.task_id,
                     change.reason, at(now))
        return out

    def subjects(self, kind: str) -> tuple[str, ...] | None:
        """Sub-keys heard per kind (the runtime subscribes to `*/murdoch/<kind>/<subject>`):
        announcements of the tasks this robot serves, bids addressed to itself; None — awards,
        claims, releases, revocations — every robot's, which every robot needs
        (docs/murdoch.md)."""
        if kind == "announcement":
            return self.core.subjects
        if kind == "bid":
            return (self.robot_id,)
        return None
