"""`delivery/deliver`: drive to the task, stay for its service time, tell the team.

The robot drives the path the cost model prices (docs/delivery.md, "Cost model"): on the first
step after each activation it plans a shortest drivable path from where it is to the task
around the world's walls (`mrta_zenoh.planning.geometry`, the same visibility graph the
instance's cost matrix comes from; a straight line in an open room) and follows its waypoints
in turn — turning towards the next, driving straight at its own speed (the instance's
`robots/<id>/speed`, its commanded cap: the simulator's robot model has one speed limit for every robot,
0.75 m/s, so robots differ in speed by what their layer commands). It reads only odometry: the
walls are known from the instance. Within `tolerance` of the task it stops, says `started`,
waits `service` seconds and says `done` (reliably: that is what makes the task inapplicable
for every teammate). Deactivated before that (a handover), it starts over when activated
again, from where it then is.

Time windows (docs/delivery.md, "Time windows"): at the task before its `earliest`, the robot
waits there, standing, and says `started` only when the window opens. Under hard windows it
never starts after the due: once even the straight line from where it is (less the tolerance)
at its speed — a lower bound of the time it needs — would get it there after the due, it gives
the task up (stands still; its window state tells the task's evaluator, which then says the task is
expired for this robot, and its architecture lets it go).

Which task a layer serves: the agent runtime's loader sets every layer's `task_id` to the
task whose layers it builds, so one registered class serves every task.
"""

from __future__ import annotations

import math

from mrta_zenoh.clock import EPSILON
from mrta_zenoh.errors import ConfigError
from mrta_zenoh.messages import Header
from mrta_zenoh.planning.geometry import PathMap
from mrta_agent.runtime.builtin import odometry_pose
from mrta_agent.runtime.plugins import AgentContext, Layer

from .board import PATHS, Board
from .windows import WindowState
from .instance import DeliveryParams, InstanceBody
from .keys import Event, event_key
from .messages import TaskEvent

ALIGNED = 0.35  # rad: beyond this heading error the robot turns (almost) in place
CORNER = 0.1    # m: a corner counts as passed this close (the path keeps 0.14 m of margin)


def _clip(v: float, lo: float, hi: float) -> float:
    return lo if v < lo else hi if v > hi else v


class Deliver(Layer):
    params_section = "Delivery"
    Params = DeliveryParams
    instance_type = InstanceBody

    def setup(self, ctx: AgentContext) -> None:
        super().setup(ctx)
        if self.task_id is None:
            raise ConfigError("delivery/deliver does not know its task: it serves a task only "
                              "when loaded from a tasks file")
        self.instance: InstanceBody = ctx.instance
        task = self.instance.task(self.task_id)
        self.goal = (float(task.position[0]), float(task.position[1]))
        self.service = task.service
        self.earliest = task.earliest or 0.0
        self.due = math.inf if task.due is None or self.instance.windows != "hard" else task.due
        self.speed = self.instance.robot(ctx.robot_id).speed
        self.board = Board.of(self)
        self.windows = WindowState.of(self)
        self.paths = path_map_of(self)
        self.seq = 0
        self.on_activate(0.0)

    def on_activate(self, now: float) -> None:
        self.serving_since: float | None = None
        self.finished = False
        self.waypoints: list[tuple[float, float]] | None = None  # planned at the next step

    def done(self, now: float) -> bool:
        """This robot served the task (its service is over) since it was last activated."""
        return self.finished

    def pose(self, now: float) -> tuple[float, float, float] | None:
        return odometry_pose(self.ctx, now)

    def step(self, now: float, dt: float) -> None:
        if self.finished or self.board.is_done(self.task_id, now):
            self.ctx.publish_cmd(0.0, 0.0)
            return
        if self.serving_since is not None:
            self.ctx.publish_cmd(0.0, 0.0)
            if now - self.serving_since >= self.service - EPSILON:
                self.finished = True
                self.board.mark_done(self.task_id, self.ctx.robot_id, now)
                self._say(Event.DONE, now)
            return
        pose = self.pose(now)
        if pose is None or self.task_id in self.windows.given_up:
            self.ctx.publish_cmd(0.0, 0.0)  # blind, or let go: stand still
            return
        if self.too_late(pose, now):
            self.windows.given_up.add(self.task_id)
            self.ctx.publish_cmd(0.0, 0.0)
            self.ctx.log.info("%s: gives %s up at t=%.2f: it cannot start by its due %g s",
                              self.ctx.robot_id, self.task_id, now, self.due)
            return
        if self.waypoints is None:
            self.waypoints = self.plan(pose)
        while len(self.waypoints) > 1 and math.hypot(self.waypoints[0][0] - pose[0],
                                                     self.waypoints[0][1] - pose[1]) \
                <= CORNER:
            self.waypoints.pop(0)  # a corner passed
        v, w, arrived = self.command(pose, self.waypoints[0], len(self.waypoints) == 1)
        if arrived:
            self.ctx.publish_cmd(0.0, 0.0)
            if now < self.earliest - EPSILON:
                return  # there early: it waits for the window to open
            self.serving_since = now
            self.windows.started.add(self.task_id)
            self._say(Event.STARTED, now)
            return
        self.ctx.publish_cmd(v, w)

    def too_late(self, pose: tuple[float, float, float], now: float) -> bool:
        """Hard windows: even the straight line from `pose` would start it after the due."""
        if math.isinf(self.due):
            return False
        gap = max(0.0, math.hypot(self.goal[0] - pose[0], self.goal[1] - pose[1])
                  - self.params.tolerance)
        return now + gap / self.speed > self.due + EPSILON

    def plan(self, pose: tuple[float, float, float]) -> list[tuple[float, float]]:
        """The waypoints still to reach (the task last): the shortest drivable path from the
        pose; just the task in an open room, or when walls close it off (logged: the cost
        model said it could be reached, so that is a fault worth seeing)."""
        if self.paths is None:
            return [self.goal]
        try:
            return self.paths.path((pose[0], pose[1]), self.goal)[1:]
        except ConfigError as exc:
            self.ctx.log.error("%s: %s; driving straight at %s", self.ctx.robot_id, exc,
                               self.task_id)
            return [self.goal]

    def command(self, pose: tuple[float, float, float], target: tuple[float, float],
                last: bool) -> tuple[float, float, bool]:
        """(linear, angular, arrived) towards `target` from `pose`: turn to face it, then drive
        at the robot's speed, slowing only in the last half metre (the P3-DX decelerates at
        0.3 m/s², so braking from full speed earlier would overshoot the tolerance). `last`:
        the target is the task (else a corner, where the robot turns)."""
        x, y, th = pose
        gx, gy = target
        dist = math.hypot(gx - x, gy - y)
        if last and dist <= self.params.tolerance:
            return 0.0, 0.0, True
        err = math.atan2(gy - y, gx - x) - th
        err = math.atan2(math.sin(err), math.cos(err))
        turn = self.params.turn_rate
        w = _clip(2.0 * err, -turn, turn)
        if abs(err) > ALIGNED:
            return 0.0, w, False
        v = min(self.speed, max(0.1, dist)) * math.cos(err)
        return v, w, False

    def _say(self, event: Event, now: float) -> None:
        self.seq += 1
        self.ctx.bus.publish(event_key(self.ctx.robot_id, event),
                             TaskEvent(Header(self.ctx.robot_id, now, self.seq), self.task_id,
                                       event.value))
        self.ctx.log.info("%s: %s %s at t=%.2f", self.ctx.robot_id, event, self.task_id, now)


def path_map_of(layer: Deliver) -> PathMap | None:
    """The robot's path map of the instance's world (None: an open room), built by its first
    delivery layer and shared by the others, as the board is."""
    return layer.ctx.share(PATHS, layer.instance.path_map)
