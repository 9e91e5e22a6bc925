"""The supervisor's monitors, read from the architecture file (rqt_mrta's `busy_robots`,
`idle_robots`, `incoming_tasks`, `allocated_tasks` topics): which key expression, message type
and field each role reads, and what the field's value means:

* `busy_robots` / `idle_robots`: a robot id; it holds that state for the topic's `timeout`.
* `incoming_tasks`: a task id waiting for a robot.
* `allocated_tasks`: a task id; its robot is the `busy_robots` value of the same sample when
  both monitors read the same key expression (ALLIANCE's broadcast carries both), otherwise
  the first chunk of the sample's key (`robot1/…`).
* Architecture names in the ROS form (`/alliance/x`) become `**/alliance/x`.
"""

from __future__ import annotations

import operator
from dataclasses import dataclass

from mrta_zenoh.fieldpath import FieldPath
from mrta_zenoh.toolchain.model import ArchitectureFile, Topic

ROLES = ("busy_robots", "idle_robots", "incoming_tasks", "allocated_tasks")


@dataclass
class Monitor:
    role: str
    topic: Topic
    key_expr: str
    path: FieldPath

    @property
    def by_sender(self) -> bool:
        """`*/…` or `**/…`: one key per robot, whose first chunk is the publishing robot."""
        return self.key_expr.split("/", 1)[0] in ("*", "**")


def group_reader(monitors: list[Monitor]):
    """One attrgetter reading every monitor's field at once, for a group of monitors of one
    type whose paths are all names; None otherwise (the full path resolves them one by one)."""
    paths = [m.path.steps for m in monitors]
    if len({m.topic.type for m in monitors}) != 1 or \
            not all(p and all(type(x) is str for x in p) for p in paths):
        return None
    r = operator.attrgetter(*(".".join(p) for p in paths))
    if len(paths) == 1:
        return lambda msg: (r(msg),)  # the same shape as the multi-field getter
    return r


def monitors_of(arch: ArchitectureFile) -> list[Monitor]:
    out = []
    for role in ROLES:
        t = getattr(arch, role)
        if t is not None:
            out.append(Monitor(role, t, t.key_expr, FieldPath.parse(t.field)))
    return out
