"""rqt_mrta's configuration model: architecture and application files (dissertation, appendices A–B).

Plain dataclasses with value equality, so "load → write → load gives an equal model" is a one-line
test. Parameter templates form a tree: `Param` leaves, `Params` groups and `Array` templates (an
array repeats its children once per index of its sibling `size` parameter, `@index@` in names).
"""

from __future__ import annotations

from dataclasses import dataclass, field

from ..keys import normalize_robot_id, validate_key_expr

PARAM_TYPES = ("bool", "int", "double", "string")
ROBOT_TYPES = ("ST", "MT")       # single-task / multi-task robots
TASK_TYPES = ("SR", "MR")        # single-robot / multi-robot tasks
ALLOCATION_TYPES = ("IA", "TA")  # instantaneous / time-extended assignment


@dataclass
class Param:
    name: str
    type: str | None = None
    value: str | None = None
    default: str | None = None
    tool_tip: str | None = None
    line: int | None = field(default=None, compare=False, repr=False)

    @property
    def mandatory(self) -> bool:
        """No default and no fixed value: the user must give one (dissertation §3.3)."""
        return not self.default and not self.value


@dataclass
class Params:
    name: str
    children: list["Node"] = field(default_factory=list)
    line: int | None = field(default=None, compare=False, repr=False)


@dataclass
class Array:
    name: str  # contains @index@
    children: list["Node"] = field(default_factory=list)
    line: int | None = field(default=None, compare=False, repr=False)


Node = Param | Params | Array


@dataclass
class Config:
    id: str
    children: list[Node] = field(default_factory=list)
    line: int | None = field(default=None, compare=False, repr=False)


@dataclass
class LaunchArg:
    name: str
    value: str | None = None
    default: str | None = None


@dataclass
class LaunchInclude:
    file: str
    args: list[LaunchArg] = field(default_factory=list)


@dataclass
class Launch:
    id: str
    includes: list[LaunchInclude] = field(default_factory=list)


@dataclass
class Topic:
    """A monitor: samples on key expression `name` of `type`, reading `field`, held for `timeout`."""

    name: str
    type: str
    field: str
    queue_size: int = 10
    timeout: float = 1.0
    line: int | None = field(default=None, compare=False, repr=False)

    @property
    def key_expr(self) -> str:
        """The Zenoh key expression the monitor subscribes to; KeyExprError if `name` is none.

        A ROS-style absolute name (`/robot1/alliance/…`, as the original files write topics)
        is matched under any prefix (`**/robot1/alliance/…`). One definition for the file
        reader (so `mrta arch validate` refuses what the supervisor would) and the supervisor."""
        name = self.name.strip()
        if name.startswith("/"):
            return "**/" + validate_key_expr(name.strip("/"))
        return validate_key_expr(name)


@dataclass
class ArchitectureFile:
    """An rqt_mrta architecture file (appendix A) as read: taxonomy, monitors, templates. Not the
    runtime contract an architecture registers (`mrta_zenoh.architectures.Architecture`)."""

    name: str
    robots_type: str
    tasks_type: str
    allocations_type: str
    busy_robots: Topic | None = None
    idle_robots: Topic | None = None
    incoming_tasks: Topic | None = None
    allocated_tasks: Topic | None = None
    config_id: str | None = None
    launch_id: str | None = None
    configs: list[Config] = field(default_factory=list)
    launches: list[Launch] = field(default_factory=list)
    widgets: list[str] = field(default_factory=list)
    source: str | None = field(default=None, compare=False, repr=False)

    @property
    def taxonomy(self) -> str:
        return f"{self.robots_type}-{self.tasks_type}-{self.allocations_type}"

    def config(self, config_id: str) -> Config | None:
        return next((c for c in self.configs if c.id == config_id), None)

    def launch(self, launch_id: str) -> Launch | None:
        return next((la for la in self.launches if la.id == launch_id), None)


@dataclass
class RobotEntry:
    """A robot of an application file. `id` is normalised here, once (`/robot1`, as the
    original project's files write it, is robot1: one key chunk, as every process, key and
    summary names it); `written` keeps the file's spelling, which a rewritten file keeps."""

    id: str
    tasks: list[str] = field(default_factory=list)
    written: str | None = field(default=None, compare=False, repr=False)

    def __post_init__(self) -> None:
        rid = normalize_robot_id(self.id)  # KeyExprError (a ConfigError) for a bad id
        if rid != self.id:
            self.written, self.id = self.written or self.id, rid


@dataclass
class ApplicationFile:
    """An rqt_mrta application file (appendix B): the architecture package it is configured for,
    its robots and their tasks, the filled configs and launches."""

    architecture: str
    name: str
    robots: list[RobotEntry] = field(default_factory=list)
    configs: list[Config] = field(default_factory=list)
    launches: list[Launch] = field(default_factory=list)
    source: str | None = field(default=None, compare=False, repr=False)
    architecture_line: int | None = field(default=None, compare=False, repr=False)

    def tasks(self) -> list[str]:
        seen: dict[str, None] = {}
        for r in self.robots:
            for t in r.tasks:
                seen.setdefault(t, None)
        return list(seen)
