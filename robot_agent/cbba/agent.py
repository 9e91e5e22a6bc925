"""CBBA in execution: one robot's bundle logic (`bundle.Cbba`) driving its route
(mrta_agent.route.own_route: the logic's path to the RouteExecutor once settled, served tasks
fed back with `served(task, at)`, teammates without progress told as gone, reports).

Settled, for CBBA: its winning-bid table (winners, bids, path, tasks served) has not changed for
`settle` seconds. CBBA is asynchronous and no robot can know that the team has converged; on a
connected team every change a teammate makes is broadcast at once and changes this robot's
table within a tick and a delivery delay, so a table quiet for `settle` seconds (ten ticks by
default) is the converged one — with every task known at the start the team sets off on it.
A range-limited or partitioned team can settle on a plan that later consensus changes; the
robot then finishes the task it is on and takes the new path (docs/cbba.md, "In execution").

The robot's pose is the logic's `position` (what its messages say, what a comm_range is
measured from), and its scores count from the mission's start (time 0) along its path.
"""

from __future__ import annotations

import logging

from mrta_zenoh.planning.insertion import Origin

from ..route.executor import Readings
from ..route.own_route import OwnRouteCoordinator
from ..route.own_route_params import OwnRouteParams
from .bundle import Cbba


class CbbaCoordinator(OwnRouteCoordinator):
    logic_kinds = Cbba.listens
    log = logging.getLogger("mrta.cbba")

    def __init__(self, robot_id: str, params: OwnRouteParams, readings: Readings):
        keys = params.robot.extra
        logic = Cbba(params.problem, robot_id, discount=keys.discount,
                     bundle_limit=keys.bundle_limit, lookahead=keys.lookahead,
                     comm_range=keys.comm_range, resend_period=keys.resend_period,
                     origin=Origin(None, 0.0))
        super().__init__(robot_id, logic, readings, params.robot.report_period,
                         params.robot.progress_timeout)
        self.settle = keys.settle
        self._table: tuple | None = None
        self._since = 0.0

    def settled(self, now: float) -> bool:
        c = self.logic
        table = (tuple(c.z), tuple(c.y), tuple(c.path), frozenset(c.done))
        if table != self._table:
            self._table, self._since = table, now
        return now - self._since >= self.settle

    def tick(self, now: float):
        pose = self.readings.pose()
        if pose is not None:
            self.logic.position = (pose[0], pose[1])
        return super().tick(now)
