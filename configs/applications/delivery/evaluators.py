"""`delivery/task_open`: the sensory feedback (ALLIANCE), progress evaluator (MURDOCH) and
route evaluator (central) of a delivery task. Applicable while the robot's sensors are fresh,
the task has arrived, nobody has completed it, the robot can serve it (capability) and has
served fewer than the instance's `max_tasks_per_robot` (unlimited by default: a robot that
delivered serves another task, time-extended assignment; 1 is instantaneous assignment). A
teammate's `done` makes it inapplicable at once: ALLIANCE drops the behaviour set, MURDOCH's
holder gives the task back and nobody bids for it again. A task cancelled at run time
(board.py) is inapplicable from the tick after its cancellation the same way; a cancelled task
and one a teammate delivered are `withdrawn`: a robot serving a route (central, SSI, CBBA)
leaves it rather than stand by it, and says so in its reports.

Sensors: a sensor that has reported and then went silent makes the task inapplicable; one that
has not reported yet does not. Whether the first odometry sample arrives before or after a
robot's first tick is a race at start-up; counting it would shift ALLIANCE's activations by a
tick from run to run, and the same seed must give the same allocation. (MURDOCH bids only with
fresh resources, its tasks file's `resources`.)

Time windows (docs/delivery.md, "Time windows"): a task is applicable before its `earliest`
(the robot may set off and wait there: its layer does not start service sooner). Under hard
windows it is *expired* for this robot — inapplicable for good, `is_expired` — once its due has
passed without this robot having begun its service, or once this robot's layer gave it up
(it could no longer get there by the due: `layers.py`); a robot serving it when the due passes
goes on. ALLIANCE drops the behaviour set of an inapplicable task, MURDOCH's holder releases it;
an expired task is also `withdrawn`, as a cancelled one is, so a route executor leaves it and
never sets off to it again."""

from __future__ import annotations

import math

from mrta_zenoh.clock import EPSILON
from mrta_agent.runtime.plugins import AgentContext, SensoryEvaluator

from .board import Board
from .windows import WindowState
from .instance import InstanceBody


class TaskOpen(SensoryEvaluator):
    instance_type = InstanceBody
    serves_submitted = True  # every delivery task is a point task: one class serves them all

    def setup(self, ctx: AgentContext) -> None:
        super().setup(ctx)
        params: InstanceBody = ctx.instance
        task = params.task(self.task_id)
        self.arrival = task.arrival
        self.due = math.inf if task.due is None else task.due
        self.hard = params.windows == "hard"
        self.capable = params.capable(ctx.robot_id, self.task_id)
        self.cap = params.max_tasks_per_robot
        self.board = Board.of(self)
        self.windows = WindowState.of(self)

    def withdrawn(self, now: float) -> bool:
        """Cancelled at run time (board.py), expired (module docstring), or delivered by a
        teammate (its done believed by the board): a route-serving robot leaves it — the
        teammate may have served it cut off from whoever plans the routes (issue 51.2)."""
        return self.board.is_cancelled(self.task_id, now) or self.is_expired(now) \
            or self.board.done_by_teammate(self.task_id, now)

    def is_applicable(self, now: float) -> bool:
        return (not self.is_expired(now) and self.capable and now >= self.arrival - EPSILON
                and all(s.latest_time is None or s.is_up_to_date(now) for s in self.sensors)
                and not self.board.is_done(self.task_id, now)
                and not self.board.is_cancelled(self.task_id, now)
                and (self.cap is None or self.board.delivered_by(self.ctx.robot_id) < self.cap))

    def is_expired(self, now: float) -> bool:
        """Hard windows: its due passed before this robot began serving it, or its layer gave
        it up (module docstring). The delivery evaluator's own, not a plugin hook."""
        return (self.hard and self.task_id not in self.windows.started
                and (now > self.due + EPSILON or self.task_id in self.windows.given_up))
