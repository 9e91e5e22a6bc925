"""TeSSI for one robot: SSI's auction (mrta_agent.ssi.auction.Ssi — its rounds, its auctioneer,
its tie rules and every rule of what a message is believed for, shared by inheritance, not
re-written) with TeSSI's bid (Nunes & Gini, AAAI 2015): a task is inserted into the robot's
schedule kept as a simple temporal network (stn.Schedule), only where the network stays
consistent, and the bid is the schedule's makespan with the task inserted — or, TeSSIduo,
`makespan_weight` · that makespan + (1 − makespan_weight) · the travel the task adds (stn.py's
docstring cites the sources). A task that fits nowhere in a
robot's schedule is not bid on by it (docs/tessi.md).

When the schedule starts. A robot on its way to its path's first task left when it finished
the last one (the origin Ssi keeps); an idle robot (an empty path) leaves now, so its bids and
its consistency checks start from the time of the tick that computes them, not from when it
became idle (docs/tessi.md, "In execution").
"""

from __future__ import annotations

from typing import Any

from mrta_zenoh.planning import Problem
from mrta_zenoh.planning.insertion import Origin

from ..runtime.coordinator import Say
from ..ssi.auction import Ssi
from .stn import Schedule


class Tessi(Ssi):
    """One robot's TeSSI: Ssi's arguments, and `makespan_weight` (1: TeSSI's makespan bid;
    below 1: TeSSIduo's combination with travel)."""

    def __init__(self, problem: Problem, robot_id: str, *, makespan_weight: float = 1.0,
                 **ssi: Any):
        super().__init__(problem, robot_id, **ssi)
        self.makespan_weight = makespan_weight
        self.now = 0.0

    def tick(self, now: float) -> list[Say]:
        self.now = now
        return super().tick(now)

    def schedule(self) -> Schedule:
        """This robot's path as a temporal network, from when it can leave (module
        docstring)."""
        origin = self.origin if self.path else Origin(self.origin.task,
                                                      max(self.origin.time, self.now))
        return Schedule(self.problem, self.i, self.path, origin)

    def insertion(self, j: int) -> tuple[float, int]:
        return self.schedule().insertion(j, self.makespan_weight)
