"""SSI in execution: one robot's auction logic (`auction.Ssi`) driving its route
(mrta_agent.route.own_route: the logic's path to the RouteExecutor once settled, served tasks
fed back with `served(task, at)`, teammates without progress told as gone, reports).

Settled, for SSI: the robot has a Round (heard, or made as the auctioneer) and no task that a
live robot could serve is still open in it — every award of the current rounds is in. With every
task known at the start the team thus sets off on SSI's final allocation, each robot on the path
its awards built (docs/ssi.md, "In execution"). Under hard windows a task nobody can insert
where its window holds stays open for good (nobody bids on it), so there a Round unchanged for
`QUIET` resend periods settles too: every award that was coming is in.

Once settled — or once tasks entered at run time, whichever comes first — a robot serves each
award as it comes, without waiting for the rounds still going on (tasks that arrive, or are submitted at run time, or a lost robot's tasks opened
again). Departure from Koenig et al. 2006, whose auction allocates every task before anyone
moves: that is the rule for the tasks known at the start, kept above. For tasks entering while
the team works it would make every robot that runs out of work stand idle until the last round
— and SSI awards one task a round, two ticks apart at best, so a burst of 200 submitted tasks
took 40 s of rounds with the whole team idle (issue 50: none of 200 served by 25 s). Waiting
buys nothing there: an SSI award is final (only a robot leaving the team has its tasks opened
again), so the later rounds only add tasks to a robot's path, never take one it holds away.
"""

from __future__ import annotations

import logging

from mrta_zenoh.planning.insertion import Origin, binding

from ..route.executor import Readings
from ..route.own_route import OwnRouteCoordinator
from ..route.own_route_params import OwnRouteParams
from .auction import Ssi
from .messages import OPEN


class SsiCoordinator(OwnRouteCoordinator):
    """`logic_class` and `logic_keys`: what an auction built on SSI's (TeSSI) changes."""

    logic_kinds = Ssi.listens
    logic_class: type[Ssi] = Ssi
    log = logging.getLogger("mrta.ssi")

    def __init__(self, robot_id: str, params: OwnRouteParams, readings: Readings):
        keys = params.robot.extra
        logic = self.logic_class(params.problem, robot_id, lookahead=keys.lookahead,
                                 resend_period=keys.resend_period, join_wait=keys.join_wait,
                                 origin=Origin(None, 0.0), silence=params.robot.progress_timeout,
                                 **self.logic_keys(keys))
        super().__init__(robot_id, logic, readings, params.robot.report_period,
                         params.robot.progress_timeout)

    def logic_keys(self, keys) -> dict:
        """The logic's own arguments from the robot file's keys (SSI: none)."""
        return {}

    def subjects(self, kind: str) -> tuple[str, ...] | None:
        """Bids go to their auctioneer (`*/ssi/bid/<auctioneer>`): only those to this robot."""
        return (self.robot_id,) if kind == "bid" else None

    # under hard windows (module docstring): the Round last seen, since when, and how many
    # resend periods it must stay unchanged to settle on tasks nobody bids on
    _round: tuple | None = None
    _round_since = 0.0
    QUIET = 2

    # settled once: later awards are served as they come (module docstring); a subclass that
    # keeps the paper's rule for every round sets `serve_as_awarded` False
    serve_as_awarded = True
    _set_off = False

    def settled(self, now: float) -> bool:
        s = self.logic
        if s.round_from is None:
            return False
        if self._set_off:
            return True
        done = self._first_allocation_in(now)
        if not self.serve_as_awarded:
            return done
        # tasks entered at run time (their indices follow the instance's): the problem is no
        # longer the static one the paper allocates whole — a burst entering before the first
        # allocation was over held every robot until all of it was awarded (5 of 200 served
        # in 60 s, benchmarks/task_served.py)
        self._set_off = done or len(s.problem.tasks) > s.base
        return self._set_off

    def _first_allocation_in(self, now: float) -> bool:
        """Every task known at the start is awarded (module docstring)."""
        s = self.logic
        team = s.alive | {s.i}
        if not any(w == OPEN and any(s.problem.capable(k, j) for k in team)
                   for j, w in enumerate(s.owners)):
            return True
        if not binding(s.problem):
            return False
        state = (s.round, tuple(s.owners))  # module docstring: quiet Rounds settle
        if state != self._round:
            self._round, self._round_since = state, now
        return now - self._round_since >= self.QUIET * s.resend_period
