"""central_msgs: the dispatcher and its robots on the bus (docs/central.md).

* `Queue` — the dispatcher to one robot (`dispatcher/central/queue/<robot>`): the tasks it is
  to serve, in order, under a version that only grows. Repeated every `resend_period`, so a
  lost one is repaired by the next and a robot knows the dispatcher is there. A version more
  than VERSION_JUMP ahead of the one applied is believed only when heard again later (the
  dispatcher repeats its queues; a forged version 2^62 said once is not), and none above
  MAX_VERSION (docs/security.md).
* `Progress` (`route_msgs/Progress`, shared with SSI and CBBA) — a robot to the dispatcher
  (`robotN/central/progress`): what it is on, its whole queue, what it served (in order), where
  it is, the queue version it applied. Sent at every change and every `report_period`: its
  progress, and its heartbeat.
* `Queued` (`route_msgs/Queued`, shared) — a robot, once per `report_period` per task of its
  queue (`robotN/central/queued/<task>`): monitoring only, what the supervisor's `busy_robots`
  and `allocated_tasks` read (a queued task is allocated, whether or not the robot is on it
  yet).
* `Plan` — the dispatcher's record of each decision (`dispatcher/central/plan`): what set it
  off, the objective's value, the method, the computation time. Monitoring: a study reads it.
"""

from __future__ import annotations

from mrta_zenoh.messages import Finite, Header, Message, message

# a robot's progress and its queued tasks are every route-serving architecture's messages
from ..route.messages import Progress, Queued  # noqa: F401  (re-exported: central's kinds)


VERSION_JUMP = 100_000  # versions ahead of the applied one a queue is believed at once
MAX_VERSION = 2 ** 48   # no queue version above: a run issues fewer by far


@message("central_msgs/Queue")
class Queue(Message):
    header: Header
    robot: str
    version: int
    tasks: tuple[str, ...] = ()


@message("central_msgs/Plan")
class Plan(Message):
    """One decision: `version` (every queue it sent carries a version ≥ it), `trigger` (start,
    arrival, completion, loss, return), the objective, the value of the plan (the served
    prefixes and the new routes, planning.schedule), how it was found (`method`: exact, best
    found, kept — the current plan was as good —, or insertion: the search found no route at
    all within its time cap, each task inserted where it adds least), `solve_ms` of
    computation, and the routes
    (`robot:task,task,…`, its whole queue each); `capped`: the search was stopped by its time
    cap (planner.Outcome.capped: the run then depends on the machine); `out`: the robots the
    dispatcher has left out of the plan, and why (`robot3:stalled`; crashed, silent) — what the
    summary reads the stalls it declared from (issue 51.2)."""

    header: Header
    version: int
    trigger: str
    objective: str
    value: Finite
    method: str
    solve_ms: Finite
    routes: tuple[str, ...] = ()
    capped: bool = False
    out: tuple[str, ...] = ()
