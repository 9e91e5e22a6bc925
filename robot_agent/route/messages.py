"""The messages of a robot serving a route, the same under every architecture whose robots serve
routes (central, SSI, CBBA): `Progress` (what it set off to, served, left; its queue; where it is)
and `Queued` (one per task of its queue, monitoring)."""

from __future__ import annotations

from mrta_zenoh.messages import Finite, Header, Message, message


@message("route_msgs/Progress")
class Progress(Message):
    """A robot's progress on its route, under every architecture whose robots serve routes
    (SSI, CBBA, central): `task`: the task it set off to ("" none); `last`: the one it last
    served or left ("" none), so a report of an idle robot still says what it stopped;
    `queue`: its whole queue; `served`: what it served, in order; where it is; `version`: the
    queue version it applied (central's dispatcher numbers its queues; 0 where the robot's own
    logic keeps its route); `holding`: it stands still although it has work (central: the
    dispatcher, alive, has been silent past its lease); `withdrawn`: the tasks it left for good
    because its evaluator said so (done by a teammate, cancelled, expired: RouteExecutor) —
    what the robot's application knows and its dispatcher may not (issue 51.2: a task that a
    robot cut off by a partition delivered unseen)."""

    header: Header
    task: str
    last: str
    queue: tuple[str, ...]
    served: tuple[str, ...]
    x: Finite
    y: Finite
    theta: Finite
    version: int = 0
    holding: bool = False
    withdrawn: tuple[str, ...] = ()


@message("route_msgs/Queued")
class Queued(Message):
    """`task_id` is in the sender's queue, at `place` (0: the task it is on)."""

    header: Header
    task_id: str
    place: int
