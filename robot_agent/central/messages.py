"""central_msgs: the dispatcher and its robots on the bus (docs/central.md).

* `Queue` — the dispatcher to one robot (`dispatcher/central/queue/<robot>`): the tasks it is
  to serve, in order, under a version that only grows. Repeated every `resend_period`, so a
  lost one is repaired by the next and a robot knows the dispatcher is there.
* `Progress` — a robot to the dispatcher (`robotN/central/progress`): what it is on, its whole
  queue, what it served (in order), the queue version it applied, where it is. Sent at every
  change and every `report_period`: its progress, and its heartbeat.
* `Queued` — a robot, once per `report_period` per task of its queue
  (`robotN/central/queued/<task>`): monitoring only, what the supervisor's `busy_robots` and
  `allocated_tasks` read (a queued task is allocated, whether or not the robot is on it yet).
* `Plan` — the dispatcher's record of each decision (`dispatcher/central/plan`): what set it
  off, the objective's value, the method, the computation time. Monitoring: a study reads it.
"""

from __future__ import annotations

from mrta_zenoh.messages import Finite, Header, Message, message


@message("central_msgs/Queue")
class Queue(Message):
    header: Header
    robot: str
    version: int
    tasks: tuple[str, ...] = ()


@message("central_msgs/Progress")
class Progress(Message):
    """`task`: the task it set off to ("" none); `last`: the one it last served or left ("" none),
    so a report of an idle robot still says what it stopped; `holding`: it stands still
    although it has work (the dispatcher, alive, has been silent past its lease)."""

    header: Header
    task: str
    last: str
    queue: tuple[str, ...]
    served: tuple[str, ...]
    version: int
    x: Finite
    y: Finite
    theta: Finite
    holding: bool = False


@message("central_msgs/Queued")
class Queued(Message):
    """`task_id` is in the sender's queue, at `place` (0: the task it is on)."""

    header: Header
    task_id: str
    place: int


@message("central_msgs/Plan")
class Plan(Message):
    """One decision: `version` (every queue it sent carries a version ≥ it), `trigger` (start,
    arrival, completion, loss, return), the objective, the value of the plan (the served
    prefixes and the new routes, planning.schedule), how it was found (`method`: exact, best
    found, or kept — the current plan was as good), `solve_ms` of computation, and the routes
    (`robot:task,task,…`, its whole queue each)."""

    header: Header
    version: int
    trigger: str
    objective: str
    value: Finite
    method: str
    solve_ms: Finite
    routes: tuple[str, ...] = ()
