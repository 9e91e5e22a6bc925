"""patrol_msgs: the team report the `report` layer publishes, and the log each robot keeps of
its own work, from which every robot's ledger builds that report (ledger.py)."""

from __future__ import annotations

from typing import Annotated

import msgspec

from mrta_zenoh.messages import Finite, Header, Message, message

# A border of 10 km a side (layers.py's coordinate bound) in 0.5 m cells: a log never needs more.
MAX_CELLS = 160_000
MAX_TASK_TIMES = 256  # a robot's own task times: one per task it has worked on


@message("patrol_msgs/TaskTime")
class TaskTime(Message):
    robot_id: str
    task_id: str
    seconds: Finite


@message("patrol_msgs/Report")
class Report(Message):
    header: Header
    distance: Finite         # metres covered by the whole team
    border_covered: Finite   # share of the border's 0.5 m cells some robot came near
    task_times: tuple[TaskTime, ...]


@message("patrol_msgs/PatrolLog")
class PatrolLog(Message):
    """One robot's own work since it started, cumulative: what it alone can say for sure.

    Published on `robotN/patrol/log` about once per Report/log_period; a teammate keeps only the
    latest, so a lost one costs nothing. `visited` is a bitmap of the border's cells (cell i is
    bit i % 8 of byte i // 8) rather than a list of indices: its size is fixed by the border
    (26 bytes for patrol's 208 cells), however much of it the robot has seen. `cells` says how
    many cells the sender's border has, so a ledger can refuse a log made for another border
    instead of merging bits that mean other places. Every task time names the sender."""

    header: Header
    distance: Annotated[float, msgspec.Meta(ge=0.0, le=1e12)]  # metres this robot covered
    cells: Annotated[int, msgspec.Meta(ge=0, le=MAX_CELLS)]
    visited: Annotated[bytes, msgspec.Meta(max_length=(MAX_CELLS + 7) // 8)]
    task_times: Annotated[tuple[TaskTime, ...], msgspec.Meta(max_length=MAX_TASK_TIMES)]
