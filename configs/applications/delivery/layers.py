"""`delivery/deliver`: drive to the task, stay for its service time, tell the team.

The robot turns towards the task and drives straight at its own speed (`Delivery/robots/<id>/
speed`, its commanded cap: the simulator's robot model has one speed limit for every robot,
0.75 m/s, so robots differ in speed by what their layer commands). It reads only odometry: a
delivery world is open, and the cost model (docs/delivery.md) is the straight line. Within
`tolerance` of the task it stops, says `started`, waits `service` seconds and says `done`
(reliably: that is what makes the task inapplicable for every teammate). Deactivated before
that (a handover), it starts over when activated again.

Which task a layer serves: the agent runtime's loader sets every layer's `task_id` to the
task whose layers it builds, so one registered class serves every task.
"""

from __future__ import annotations

import math

from mrta_zenoh.clock import EPSILON
from mrta_zenoh.errors import ConfigError
from mrta_zenoh.messages import Header
from mrta_agent.runtime.builtin import odometry_pose
from mrta_agent.runtime.plugins import AgentContext, Layer

from .board import Board
from .instance import DeliveryParams
from .keys import event_key
from .messages import TaskEvent

ALIGNED = 0.35  # rad: beyond this heading error the robot turns (almost) in place


def _clip(v: float, lo: float, hi: float) -> float:
    return lo if v < lo else hi if v > hi else v


class Deliver(Layer):
    params_section = "Delivery"
    Params = DeliveryParams

    def setup(self, ctx: AgentContext) -> None:
        super().setup(ctx)
        if self.task_id is None:
            raise ConfigError("delivery/deliver does not know its task: it serves a task only "
                              "when loaded from a tasks file")
        task = self.params.task(self.task_id)
        self.goal = (float(task.position[0]), float(task.position[1]))
        self.service = task.service
        self.speed = self.params.robot(ctx.robot_id).speed
        self.board = Board.of(self)
        self.seq = 0
        self.on_activate(0.0)

    def on_activate(self, now: float) -> None:
        self.serving_since: float | None = None
        self.finished = False

    def pose(self, now: float) -> tuple[float, float, float] | None:
        return odometry_pose(self.ctx, now)

    def step(self, now: float, dt: float) -> None:
        if self.finished or self.board.is_done(self.task_id):
            self.ctx.publish_cmd(0.0, 0.0)
            return
        if self.serving_since is not None:
            self.ctx.publish_cmd(0.0, 0.0)
            if now - self.serving_since >= self.service - EPSILON:
                self.finished = True
                self.board.mark_done(self.task_id, self.ctx.robot_id, now)
                self._say("done", now)
            return
        pose = self.pose(now)
        if pose is None:
            self.ctx.publish_cmd(0.0, 0.0)  # blind: stand still
            return
        v, w, arrived = self.command(pose)
        if arrived:
            self.serving_since = now
            self.ctx.publish_cmd(0.0, 0.0)
            self._say("started", now)
            return
        self.ctx.publish_cmd(v, w)

    def command(self, pose: tuple[float, float, float]) -> tuple[float, float, bool]:
        """(linear, angular, arrived) towards the goal from `pose`: turn to face it, then drive
        at the robot's speed, slowing only in the last half metre (the P3-DX decelerates at
        0.3 m/s², so braking from full speed earlier would overshoot the tolerance)."""
        x, y, th = pose
        gx, gy = self.goal
        dist = math.hypot(gx - x, gy - y)
        if dist <= self.params.tolerance:
            return 0.0, 0.0, True
        err = math.atan2(gy - y, gx - x) - th
        err = math.atan2(math.sin(err), math.cos(err))
        turn = self.params.turn_rate
        w = _clip(2.0 * err, -turn, turn)
        if abs(err) > ALIGNED:
            return 0.0, w, False
        v = min(self.speed, max(0.1, dist)) * math.cos(err)
        return v, w, False

    def _say(self, event: str, now: float) -> None:
        self.seq += 1
        self.ctx.bus.publish(event_key(self.ctx.robot_id, event),
                             TaskEvent(Header(self.ctx.robot_id, now, self.seq), self.task_id,
                                       event))
        self.ctx.log.info("%s: %s %s at t=%.2f", self.ctx.robot_id, event, self.task_id, now)
