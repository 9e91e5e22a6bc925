"""`delivery/task_open`: the sensory feedback (ALLIANCE), progress evaluator (MURDOCH) and
route evaluator (central) of a delivery task. Applicable while the robot's sensors are fresh,
the task has arrived, nobody has completed it, the robot can serve it (capability) and has
served fewer than the instance's `max_tasks_per_robot` (unlimited by default: a robot that
delivered serves another task, time-extended assignment; 1 is instantaneous assignment). A
teammate's `done` makes it inapplicable at once: ALLIANCE drops the behaviour set, MURDOCH's
holder gives the task back and nobody bids for it again. A task cancelled at run time
(board.py) is inapplicable from the tick after its cancellation the same way, and `withdrawn`:
a robot serving a route (central, SSI, CBBA) leaves it rather than stand by it.

Sensors: a sensor that has reported and then went silent makes the task inapplicable; one that
has not reported yet does not. Whether the first odometry sample arrives before or after a
robot's first tick is a race at start-up; counting it would shift ALLIANCE's activations by a
tick from run to run, and the same seed must give the same allocation. (MURDOCH bids only with
fresh resources, its tasks file's `resources`.)"""

from __future__ import annotations

from mrta_zenoh.clock import EPSILON
from mrta_agent.runtime.plugins import AgentContext, SensoryEvaluator

from .board import Board
from .instance import InstanceBody


class TaskOpen(SensoryEvaluator):
    instance_type = InstanceBody

    def setup(self, ctx: AgentContext) -> None:
        super().setup(ctx)
        params: InstanceBody = ctx.instance
        self.arrival = params.task(self.task_id).arrival
        self.capable = params.capable(ctx.robot_id, self.task_id)
        self.cap = params.max_tasks_per_robot
        self.board = Board.of(self)

    def withdrawn(self, now: float) -> bool:
        """Cancelled at run time (board.py): a route-serving robot leaves it."""
        return self.board.is_cancelled(self.task_id, now)

    def is_applicable(self, now: float) -> bool:
        return (self.capable and now >= self.arrival - EPSILON
                and all(s.latest_time is None or s.is_up_to_date(now) for s in self.sensors)
                and not self.board.is_done(self.task_id)
                and not self.board.is_cancelled(self.task_id, now)
                and (self.cap is None or self.board.delivered_by(self.ctx.robot_id) < self.cap))
