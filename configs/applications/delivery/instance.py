"""The delivery instance document (docs/delivery.md, "Instances"): robots (start, heading, speed,
capabilities), tasks (position, arrival, service, capability, reward, time window: `earliest`,
`due`), whether windows are `hard` or `soft`, and the world (room size, walls), as a YAML file states it and as summary.json's `instance` section writes it back.
Typed (msgspec), so a bad value is an error naming file, line and key before anything runs.

Every package derived from an instance (one per architecture) holds it once, as
`config/instance.yaml`, which its layers file names (mrta_agent.runtime.instance) and the
delivery plugins read as `ctx.instance`; the layers file's `Delivery` section holds only how the
layer drives (`DeliveryParams`). So every robot, whatever its architecture, and the mission hook
read one instance. The travel model is `mrta_zenoh.planning`'s: straight lines in an open room,
shortest drivable paths around the walls otherwise (`planning.geometry`).
"""

from __future__ import annotations

import functools
import math
from collections import Counter
from pathlib import Path
from typing import Annotated, Any, Literal

import msgspec
import yaml

from mrta_zenoh.errors import ConfigError
from mrta_zenoh.keys import is_id
from mrta_zenoh.messages import Finite
from mrta_zenoh.planning import Problem, Robot, Task, Windows
from mrta_zenoh.planning.flow import serves_all
from mrta_zenoh.planning.geometry import PathMap, room_walls
from mrta_zenoh.yamlfile import YamlDoc, did_you_mean, get_path, load_yaml

Point = Annotated[tuple[Finite, Finite], msgspec.Meta(title="x, y in metres")]
NonNegative = Annotated[float, msgspec.Meta(ge=0.0, le=1e9)]
Positive = Annotated[float, msgspec.Meta(gt=0.0, le=100.0)]
Size = Annotated[float, msgspec.Meta(gt=0.0, le=10_000.0)]
Wall = tuple[Finite, Finite, Finite, Finite]

# An instance's sizes are bounded (issue 51.5): every process of a run holds the
# (robots + tasks)² travel-time matrix, and every robot builds the visibility graph of the walls
# (≈ 10 corners a wall, pairs of corners checked against every wall). Above these caps a file
# is refused at once, naming the cap, rather than costing minutes or gigabytes in every process.
# Robots go to 1,000 because agent hosts are for team sizes up to 1,000 (issue 47; a host speaks
# for up to 1,024): 1,000 robots and 1,000 tasks make a 2,000² matrix of 32 MB, once per process.
MAX_ROBOTS = 1000
MAX_TASKS = 1000
MAX_WALLS = 50
MATRIX = "every process of a run holds the (robots + tasks)² travel-time matrix"
CAPS = (("robots", "MAX_ROBOTS", MAX_ROBOTS, "robots", MATRIX),
        ("tasks", "MAX_TASKS", MAX_TASKS, "tasks", MATRIX),
        ("world/walls", "MAX_WALLS", MAX_WALLS, "inner walls",
         "every robot builds the walls' visibility graph"))


class RobotSpec(msgspec.Struct, forbid_unknown_fields=True):
    start: Point
    speed: Positive                      # m/s the robot drives at (its commanded cap)
    capabilities: tuple[str, ...] = ()
    heading: Finite = 0.0                # degrees, the start heading


class TaskSpec(msgspec.Struct, forbid_unknown_fields=True):
    position: Point
    arrival: NonNegative = 0.0           # s: when the task appears
    service: NonNegative = 0.0           # s: how long a robot must stay at it
    capability: str = ""                 # what it needs ("": any robot)
    reward: Finite = 1.0                 # what serving it is worth
    # its time window (docs/delivery.md, "Time windows"); None: no bound
    earliest: NonNegative | None = None  # s: service may not start before (a robot waits)
    due: NonNegative | None = None       # s: service must start by (hard) or is late (soft)


class WorldSpec(msgspec.Struct, forbid_unknown_fields=True, frozen=True):
    size: tuple[Size, Size] = (12.0, 8.0)   # m: the room, centred on the origin (its 4 walls)
    # m: walls inside it, x1, y1, x2, y2
    walls: Annotated[tuple[Wall, ...], msgspec.Meta(max_length=MAX_WALLS)] = ()

    def all_walls(self) -> list[tuple[float, float, float, float]]:
        return room_walls(*self.size) + [tuple(map(float, w)) for w in self.walls]


DEFAULT_WORLD = WorldSpec()


class InstanceBody(msgspec.Struct, forbid_unknown_fields=True):
    robots: Annotated[dict[str, RobotSpec], msgspec.Meta(max_length=MAX_ROBOTS)] = {}
    tasks: Annotated[dict[str, TaskSpec], msgspec.Meta(max_length=MAX_TASKS)] = {}
    world: WorldSpec = DEFAULT_WORLD
    name: str = ""                       # what results carry (a generator's, or the file's stem)
    # the most tasks one robot serves (None: as many as it likes — time-extended assignment;
    # 1: instantaneous assignment, each robot one task)
    max_tasks_per_robot: Annotated[int, msgspec.Meta(ge=1, le=1_000_000)] | None = None
    # how a due binds: hard (not started by its due: missed) or soft (served late, counted)
    windows: Literal["hard", "soft"] = Windows.HARD.value

    def robot(self, robot_id: str) -> RobotSpec:
        spec = self.robots.get(robot_id)
        if spec is None:
            raise ConfigError(f"Delivery/robots has no entry for {robot_id!r} (it has: "
                              f"{', '.join(self.robots) or 'none'})")
        return spec

    def task(self, task_id: str) -> TaskSpec:
        spec = self.tasks.get(task_id)
        if spec is None:
            raise ConfigError(f"Delivery/tasks has no task {task_id!r} (it has: "
                              f"{', '.join(self.tasks) or 'none'})")
        return spec

    def capable(self, robot_id: str, task_id: str) -> bool:
        need = self.task(task_id).capability
        return not need or need in self.robot(robot_id).capabilities

    def path_map(self) -> PathMap | None:
        """Shortest drivable paths in the world; None when it has no inner wall (then, in a
        convex room, the straight line is the shortest path)."""
        return PathMap(self.world.all_walls()) if self.world.walls else None

    def faults(self) -> list[tuple[tuple, str]]:
        """What the types cannot say, as (key path, message): every task some robot can serve,
        and startable within its window, every start and task inside the room and clear of its
        walls, ids that are one key chunk, capacity for every task."""
        out = [((group, key), f"{what} id {key!r:.80} is not one key chunk: use up to 64 "
                              "letters, digits, '_', '-' or '.' (ids appear in keys)")
               for group, what, ids in (("robots", "robot", self.robots),
                                        ("tasks", "task", self.tasks))
               for key in ids if not is_id(key)]
        for tid, t in self.tasks.items():
            if not any(self.capable(rid, tid) for rid in self.robots):
                out.append((("tasks", tid, "capability"),
                            f"no robot has capability {t.capability!r}"))
            opens = max(t.arrival, t.earliest or 0.0)
            if t.due is not None and t.due < opens:
                out.append((("tasks", tid, "due"),
                            f"due {t.due:g} s is before the task "
                            f"{'arrives' if opens == t.arrival else 'may start'} ({opens:g} s): "
                            "it could never be served"))
        if not any(key[-1] == "capability" for key, _ in out):
            out += self._capacity_faults()
        paths = PathMap(self.world.all_walls())
        w, h = self.world.size
        where = [(("robots", rid, "start"), f"robot {rid}", r.start)
                 for rid, r in self.robots.items()]
        where += [(("tasks", tid, "position"), f"task {tid}", t.position)
                  for tid, t in self.tasks.items()]
        for key, what, p in where:
            if abs(p[0]) >= w / 2 or abs(p[1]) >= h / 2:
                out.append((key, f"{what} at ({p[0]:g}, {p[1]:g}) is outside the {w:g} × {h:g} m "
                                 "room"))
                continue
            try:
                paths.check_point(tuple(p), what)
            except ConfigError as exc:
                out.append((key, str(exc)))
        if self.world.walls and not out:  # what problem()'s matrix would refuse at every run
            cut = paths.unreachable([p for _, _, p in where])
            if cut is not None:
                (_, first, a), (key, what, b) = where[cut[0]], where[cut[1]]
                out.append((key, f"{what} at ({b[0]:g}, {b[1]:g}) cannot be reached from {first} "
                                 f"at ({a[0]:g}, {a[1]:g}): walls close it off"))
        return out

    def _capacity_faults(self) -> list[tuple[tuple, str]]:
        """max_tasks_per_robot too small for every task to have a capable robot with room:
        what the reference's routing (and so every run) refuses. A flow check over task needs
        and robots' capability sets (planning.flow.serves_all)."""
        cap = self.max_tasks_per_robot
        if cap is None or not self.tasks:
            return []
        needs = Counter(t.capability for t in self.tasks.values())
        kinds = Counter(frozenset(r.capabilities) for r in self.robots.values())
        served = serves_all(needs, {k: n * cap for k, n in kinds.items()},
                            lambda need, caps: not need or need in caps)
        if served >= len(self.tasks):
            return []
        return [(("max_tasks_per_robot",),
                 f"{cap} tasks per robot leaves {len(self.tasks) - served} of "
                 f"{len(self.tasks)} tasks without a capable robot with room: no run can serve "
                 "every task")]

    def check(self) -> None:
        for _, message in self.faults()[:1]:
            raise ConfigError(message)

    def problem(self) -> Problem:
        """The planning problem (file order), distances around the walls when there are any."""
        robots = tuple(Robot(rid, (float(r.start[0]), float(r.start[1])), r.speed,
                             frozenset(r.capabilities), capacity=self.max_tasks_per_robot)
                       for rid, r in self.robots.items())
        tasks = tuple(self.planning_task(tid) for tid in self.tasks)
        paths = self.path_map()
        distance = () if paths is None else paths.matrix([r.start for r in robots]
                                                         + [t.position for t in tasks])
        return Problem(robots, tasks, distance, Windows(self.windows))

    def planning_task(self, tid: str) -> Task:
        """Task `tid` as planners see it (`problem`)."""
        t = self.tasks[tid]
        return Task(tid, (float(t.position[0]), float(t.position[1])), t.arrival, t.service,
                    t.capability, t.reward, t.earliest or 0.0,
                    math.inf if t.due is None else t.due)

    def grown_problem(self, before: Problem) -> Problem:
        """`problem` from the one `before` it grew at run time (InstanceKind.grown_problem):
        only the new tasks' distances computed, around the walls when there are any."""
        known = {t.id for t in before.tasks}
        new = [self.planning_task(tid) for tid in self.tasks if tid not in known]
        return before.grown(new, _paths(self.world).length if self.world.walls else None)

    def travel_model(self) -> str:
        if self.world.walls:
            return (f"shortest drivable path around the walls (visibility graph, clearance "
                    f"{self.path_map().clearance:g} m) / speed (s)")
        return "straight-line distance / speed (s)"


class DeliveryParams(msgspec.Struct, forbid_unknown_fields=True):
    """The layers file's `Delivery` section: how the layer drives (the instance it serves is
    the file the layers file names), and how long the run's task watch waits before it calls
    a task missed under hard windows (`miss_grace`, read by the mission hook, not the robots:
    mission.DeliveryWatch).

    `miss_grace` is simulated seconds past a task's due (or, once its service was started,
    past that service's end) with no `started` (or `done`) believed. It is a margin for word
    in flight, not a window's extension: a robot never starts a task after its due whatever it
    is, and the figures end at the due (metrics.done_at), so the grace moves only when the
    run stops. Too short, and a `started` stamped by the due but delayed on the network may
    come after the watch called the task missed — the run may then be stopped while its robot
    serves it; at most a minute, since it delays the end of every run with a missed task."""

    tolerance: Annotated[float, msgspec.Meta(gt=0.0, le=5.0)] = 0.3  # m: "at the task"
    turn_rate: Annotated[float, msgspec.Meta(gt=0.0, le=3.0)] = 1.2   # rad/s at most
    miss_grace: Annotated[float, msgspec.Meta(ge=0.0, le=60.0)] = 2.0  # s (docstring)


class SubmittedChange(msgspec.Struct, forbid_unknown_fields=True, omit_defaults=True):
    """One change that entered a live run at `at` (mrta_zenoh.tasks, `tasks/change`): a task
    submitted (`task`, which arrives then), cancelled or given a new priority — as a summary's
    instance keeps it, so that a run of that instance replays it through its intake."""

    at: NonNegative
    op: str                              # submit | cancel | reprioritize
    id: str
    task: TaskSpec | None = None         # submit: the task's fields (its arrival: `at`)
    priority: int = 0
    submitter: str = ""


class InstanceDoc(InstanceBody, forbid_unknown_fields=True):
    """An instance file. `generator` says where it came from; `cost` and `cost_model` are what
    summary.json adds to it — accepted and ignored, so a summary's section runs again as is;
    `submitted`, what entered a live run at run time and when, replays through the run's
    intake (it is no part of the body: the packages and the digest are the instance's own)."""

    application: str = ""                # "delivery" (or nothing)
    generator: dict[str, Any] = {}
    cost: Any = None
    cost_model: Any = None
    submitted: list[SubmittedChange] = []

    def body(self) -> InstanceBody:
        """The instance alone (what a package is derived from), without where it came from."""
        return InstanceBody(self.robots, self.tasks, self.world, self.name,
                            self.max_tasks_per_robot, self.windows)


def admit_task(inst: InstanceBody, task_id: str, fields: dict[str, Any]) -> TaskSpec:
    """A task submitted at run time (mrta_zenoh.tasks), checked as an instance file's task is:
    its fields typed, some robot able to serve it, inside the room and clear of its walls
    (ConfigError naming the field). Its `arrival` is the instant it enters the run, so the
    field is not taken."""
    known = [f for f in TaskSpec.__struct_fields__ if f != "arrival"]
    for key in fields:
        if key == "arrival":
            raise ConfigError("arrival: a task submitted at run time arrives when it enters "
                              "the run")
        if key not in known:
            raise ConfigError(f"unknown field {key!r}" + did_you_mean(str(key), known)
                              + f" (fields: {', '.join(known)})")
    try:
        spec = msgspec.convert(fields, TaskSpec)
    except msgspec.ValidationError as exc:
        raise ConfigError(str(exc).replace("$.", "")) from None
    if spec.capability and not any(spec.capability in r.capabilities
                                   for r in inst.robots.values()):
        raise ConfigError(f"capability: no robot has capability {spec.capability!r}")
    if spec.due is not None and spec.earliest is not None and spec.due < spec.earliest:
        raise ConfigError(f"due: {spec.due:g} s is before earliest ({spec.earliest:g} s): it "
                          "could never be served")
    p, (w, h) = spec.position, inst.world.size
    if abs(p[0]) >= w / 2 or abs(p[1]) >= h / 2:
        raise ConfigError(f"position: ({p[0]:g}, {p[1]:g}) is outside the {w:g} × {h:g} m room")
    try:
        _paths(inst.world).check_point(tuple(p), f"task {task_id}")
    except ConfigError as exc:
        raise ConfigError(f"position: {exc}") from None
    return spec


@functools.lru_cache(maxsize=8)
def _paths(world: WorldSpec) -> PathMap:
    """A world's path map, made once (a submission is checked against it at run time)."""
    return PathMap(world.all_walls())


def load_document(path: Path | str) -> InstanceDoc:
    """An instance file, checked (ConfigError naming file, line and key). A summary.json is
    read too: its `instance` section is the document. The name defaults to the file's stem."""
    return document_of(load_yaml(path))


def document_of(doc: YamlDoc) -> InstanceDoc:
    """load_document's, from the parsed file."""
    base: tuple = ()
    if isinstance(doc.data, dict) and isinstance(doc.data.get("instance"), dict):
        base = ("instance",)  # a summary.json (an instance document has no such key)
    for key, name, cap, what, why in CAPS:  # before any conversion: a huge file costs little
        where = base + tuple(key.split("/"))
        entries = get_path(doc.data, where)
        if isinstance(entries, (dict, list)) and len(entries) > cap:
            raise doc.error(where, f"{len(entries)} {what}: an instance has at most {cap} "
                                   f"({name}: {why})")
    for group, kind in (("robots", RobotSpec), ("tasks", TaskSpec)):
        entries = get_path(doc.data, base + (group,))
        if isinstance(entries, dict):  # entry by entry: an error then names its entry's line
            for key in entries:
                doc.convert(base + (group, key), kind)
    inst = doc.convert(base, InstanceDoc)
    if inst.application not in ("", "delivery"):
        raise doc.error(base + ("application",), f"this is a {inst.application!r} instance, "
                        "not a delivery one")
    raise_faults(doc, base, inst)
    if not inst.name:
        inst = msgspec.structs.replace(inst, name=Path(doc.path).stem)
    return inst


def raise_faults(doc: YamlDoc, base: tuple, inst: InstanceBody) -> None:
    if not inst.robots:
        raise doc.error(base + ("robots",), "an instance needs at least one robot")
    for key, message in inst.faults()[:1]:
        raise doc.error(base + key, message)


def document_data(inst: InstanceBody) -> dict[str, Any]:
    """The document as plain data in its own order: lists for points, no empty defaults."""
    body = msgspec.to_builtins(inst)
    for r in body["robots"].values():
        r["start"] = list(r["start"])
        r["capabilities"] = list(r["capabilities"])
    for t in body["tasks"].values():
        t["position"] = list(t["position"])
        for key in ("earliest", "due"):
            if t.get(key) is None:
                t.pop(key, None)
    body["world"] = {"size": list(inst.world.size), "walls": [list(w) for w in inst.world.walls]}
    for key in ("application", "generator", "cost", "cost_model", "max_tasks_per_robot",
                "submitted"):
        if not body.get(key):
            body.pop(key, None)
    if body.get("windows") == Windows.HARD.value:  # the default: today's files stay as they are
        body.pop("windows")
    return body


def flow(value: Any) -> str:
    text = yaml.safe_dump(value, default_flow_style=True, width=math.inf, sort_keys=False)
    return text.removesuffix("\n...\n").strip()  # a scalar's document-end marker


def document_yaml(body: dict[str, Any], indent: str = "") -> str:
    """`body` (document_data's) as YAML, one line per robot and task, in its own order."""
    lines = []
    for key, value in body.items():
        if key in ("robots", "tasks") and value:
            lines.append(f"{indent}{key}:")
            lines += [f"{indent}  {flow(k)}: {flow(v)}" for k, v in value.items()]
        else:
            lines.append(f"{indent}{flow(key)}: {flow(value)}")
    return "\n".join(lines) + "\n"
