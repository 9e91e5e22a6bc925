"""What Foxglove (or Lichtblick) shows: the bus, a 3-D scene, poses, the supervisor's state.

Channels, for a recording (McapRecorder) and for the live WebSocket server alike:

* every bus key, as JSON with a JSON Schema (mrta_zenoh.recording): motivations plot directly
  (`robotN/alliance/motivation/<task>` → `.motivation`, `.impatience`, …);
* `/world` (`foxglove.SceneUpdate`): walls, each robot as a disc with its heading and id label,
  its sonar beams, and its trail;
* `/robots/<id>/pose` (`foxglove.PoseInFrame`, frame `world`);
* `/robots/<id>/task` (JSON: state, task, and `activity` — the task while busy, else the
  state) — what the State Transitions panel draws as the allocation timeline, one row a robot;
* `/supervisor/state` (JSON: the supervisor snapshot) and `/supervisor/alarms`
  (`foxglove.Log`: each alarm raised or cleared, for the Log panel).

The scene and poses are one frame (`scene_frame`), the supervisor's channels another
(`supervisor_frame`): the caller samples each at its own rate (supervisor/live/viewer.py: per
simulated period on simulated time). Every JSON channel has a real JSON Schema (ROBOT_TASK,
SUPERVISOR_SNAPSHOT below), so Foxglove's panels offer their fields.

The scene is built from bus data only (the simulator's `world`, `*/ground_truth`, `*/sonar`), so
it needs no world file and knows no application — given the application's robots, it draws
those only (Scene). The well-known schemas and their protobuf encoding come from the official
`foxglove-sdk` package. docs/foxglove.md says why the channels are as they are.
"""

from __future__ import annotations

import collections
import functools
import json
import logging
import math
import threading
from typing import Callable

from foxglove.messages import (
    ArrowPrimitive, Color, CylinderPrimitive, LinePrimitive, LinePrimitiveLineType, Log,
    LogLevel, Point3, Pose, PoseInFrame, Quaternion, SceneEntity, SceneUpdate, TextPrimitive,
    Timestamp, Vector3,
)

from mrta_zenoh.keys import first_chunk
from mrta_zenoh.untrusted import visible

from .api import to_json

log = logging.getLogger("mrta.view")
Emit = Callable[[str, tuple[str, str, bytes], str, bytes, int], None]  # topic, schema, enc, data, t

# Foxglove's and Lichtblick's JSON Schema parsers take one type string per property, never
# "null" (mrta_zenoh.flat_schema): a value that may be null (a non-finite number, api.to_json;
# a robot without a task) is declared by its type, not required, and left out of the message
# when null (`_without_nulls`), so each message still validates against its schema.
_NUMBER = {"type": "number"}
_STRING = {"type": "string"}
_STRINGS = {"type": "array", "items": _STRING}
_INTEGER = {"type": "integer"}


def _object(required: dict, **optional) -> dict:
    return {"type": "object", "properties": {**required, **optional}, "required": list(required)}


ROBOT_TASK = {
    "title": "mrta.RobotTask",
    "description": "A robot's state and the task it is on, for the State Transitions panel.",
    **_object({"state": {**_STRING, "description": "busy, idle, offline or unknown"},
               "task": {**_STRING, "description": "the task it is allocated, '-' for none"},
               "activity": {**_STRING, "description": "the task while busy, else the state: "
                            "one State Transitions row per robot says both"}}),
}
# the supervisor's counts (supervisor/live/state.py); a newer supervisor's other counts still
# validate (additionalProperties), though the panels offer only these
COUNTS = ("samples", "wrong_type", "field_errors", "key_mismatch", "unknown", "unknown_overflow",
          "bad_keys", "stranger_tokens")
# the snapshot of docs/architecture.md ("The supervisor snapshot"); extra fields are allowed so
# that a newer supervisor's snapshot still validates
SUPERVISOR_SNAPSHOT = {
    "title": "mrta.SupervisorSnapshot",
    "description": "The supervisor's view: robots, tasks, alarms, recent transitions, counts.",
    **_object({
        "time": {**_NUMBER, "description": "the supervisor's time (simulated seconds on sim time)"},
        "application": _STRING,
        "architecture": _STRING,
        "robots": {"type": "array", "items": _object(
            {"id": _STRING, "state": {**_STRING, "description": "busy, idle, offline or unknown"},
             "online": {"type": "boolean"}, "since": _NUMBER},
            task={**_STRING, "description": "the task it is on; absent when none"})},
        "tasks": {"type": "array", "items": _object({
            "id": _STRING,
            "state": {**_STRING, "description": "allocated, incoming or unallocated"},
            "robots": _STRINGS, "since": _NUMBER})},
        "alarms": {"type": "array", "items": _object({
            "kind": _STRING, "subject": _STRING, "since": _NUMBER})},
        "transitions": {"type": "array", "items": _object({
            "time": _NUMBER,
            "kind": {**_STRING, "description": "robot, task, allocation or alarm"},
            "subject": _STRING}, **{
            "from": {**_STRING, "description": "absent for a first state"},
            "to": {**_STRING, "description": "absent when the state ended"}})},
        "counts": {"type": "object", "properties": {c: _INTEGER for c in COUNTS},
                   "additionalProperties": _INTEGER},
    }, ros2={**_object({"domain": _INTEGER, "nodes": _STRINGS,
                        "topics": {"type": "array", "items": _object({
                            "topic": _STRING, "types": _STRINGS,
                            "publishers": _INTEGER,
                            "subscriptions": _INTEGER})},
                        "invalid_tokens": _INTEGER}),
             "description": "the ROS 2 graph (docs/ros2.md)"}),
}
ROBOT_TASK_SCHEMA = ("mrta.RobotTask", "jsonschema", json.dumps(ROBOT_TASK).encode())
SUPERVISOR_SNAPSHOT_SCHEMA = ("mrta.SupervisorSnapshot", "jsonschema",
                              json.dumps(SUPERVISOR_SNAPSHOT).encode())
TRAIL = 300  # poses kept per robot
MAX_BEAMS = 32  # sonar points drawn per robot (a Pioneer has 16)
# robots drawn without an application to say which; beyond, counted (Scene.ignored): a flood of
# invented robots must not make every frame megabytes nor the view's memory grow
MAX_SCENE_ROBOTS = 32
WALLS_WAIT_NS = 1_000_000_000  # a scene frame waits this long (log time) for the world's walls
GREY, BLUE, ORANGE, WHITE, YELLOW = (
    Color(r=.6, g=.6, b=.6, a=1), Color(r=.2, g=.5, b=1, a=1), Color(r=1, g=.6, b=.1, a=.8),
    Color(r=1, g=1, b=1, a=1), Color(r=1, g=.85, b=.1, a=1))
ROBOT_RADIUS = 0.25  # m, a Pioneer 3-DX body as drawn (the simulator models 0.26: sonars included)
# A robot's name: in metres (not scale-invariant pixels, whose box covered the robot and its
# heading at a world-wide zoom), centred above the disc with a gap, so it is beside the robot
# at every zoom
LABEL_SIZE = 0.4  # m, the text's height
LABEL_ABOVE = ROBOT_RADIUS + 0.15 + LABEL_SIZE / 2  # m from the robot's centre to the label's


@functools.cache
def _schema(cls) -> tuple[str, str, bytes]:
    s = cls.get_schema()
    return s.name, s.encoding, s.data


def _quat(theta: float) -> Quaternion:
    return Quaternion(x=0.0, y=0.0, z=math.sin(theta / 2), w=math.cos(theta / 2))


def _pose(x: float, y: float, theta: float, z: float = 0.0) -> Pose:
    return Pose(position=Vector3(x=x, y=y, z=z), orientation=_quat(theta))


def _stamp(t_ns: int) -> Timestamp:
    return Timestamp(sec=t_ns // 1_000_000_000, nsec=t_ns % 1_000_000_000)


class Scene:
    """Walls, robots, beams and trails, from the bus; bounded: the application's robots only
    (`robots`), or the first MAX_SCENE_ROBOTS without one — any other robot's samples are
    counted in `ignored` — so a frame's size and the memory behind it do not grow with what
    others publish."""

    def __init__(self, robots: list[str] | None = None) -> None:
        self._lock = threading.Lock()
        self.allowed = frozenset(robots) if robots is not None else None
        self.walls: list[tuple[float, float, float, float]] = []
        self.poses: dict[str, tuple[float, float, float]] = {}
        self.trails: dict[str, collections.deque] = {}
        self.beams: dict[str, list[tuple[float, float]]] = {}
        self.ignored = 0

    def _drawn(self, robot: str) -> bool:
        if robot in self.poses or robot in self.beams:
            return True
        if self.allowed is not None:
            ok = robot in self.allowed
        else:
            ok = len(set(self.poses) | set(self.beams)) < MAX_SCENE_ROBOTS
        if not ok:
            self.ignored += 1
            if self.ignored == 1:  # once: the rest are counted (the supervisor alarms strangers)
                log.warning("the scene draws %s only; ignoring %s and any other robot",
                            "the application's robots" if self.allowed is not None
                            else f"the first {MAX_SCENE_ROBOTS} robots", visible(robot, 100))
        return ok

    def on_sample(self, key: str, message) -> None:
        with self._lock:
            if key == "world":
                self.walls = [(w.x1, w.y1, w.x2, w.y2) for w in message.walls]
            elif key.endswith("/ground_truth"):
                robot, p = first_chunk(key), message.pose
                if self._drawn(robot):
                    self.poses[robot] = (p.x, p.y, p.theta)
                    self.trails.setdefault(robot, collections.deque(maxlen=TRAIL)).append(
                        (p.x, p.y))
            elif key.endswith("/sonar"):
                robot = first_chunk(key)
                if self._drawn(robot):
                    self.beams[robot] = [(q.x, q.y) for q in message.points[:MAX_BEAMS]]

    def update(self) -> SceneUpdate:
        with self._lock:
            ents = [SceneEntity(id="walls", frame_id="world", lines=[LinePrimitive(
                type=LinePrimitiveLineType.LineList, thickness=0.08, color=GREY,
                points=[Point3(x=a, y=b, z=0) for x1, y1, x2, y2 in self.walls
                        for a, b in ((x1, y1), (x2, y2))])])]
            for robot, (x, y, th) in sorted(self.poses.items()):
                beams = [Point3(x=v, y=w, z=0.1) for bx, by in self.beams.get(robot, [])
                         for v, w in ((x, y), (x + bx * math.cos(th) - by * math.sin(th),
                                               y + bx * math.sin(th) + by * math.cos(th)))]
                d = 2 * ROBOT_RADIUS
                ents.append(SceneEntity(
                    id=robot, frame_id="world",
                    cylinders=[CylinderPrimitive(pose=_pose(x, y, th),
                                                 size=Vector3(x=d, y=d, z=0.25),
                                                 bottom_scale=1, top_scale=1, color=BLUE)],
                    # above the disc, from its centre to past its rim: seen from the top-down
                    # camera, in a colour the disc and the trail do not have
                    arrows=[ArrowPrimitive(pose=_pose(x, y, th, z=0.3), shaft_length=0.3,
                                           shaft_diameter=0.08, head_length=0.2,
                                           head_diameter=0.22, color=YELLOW)],
                    texts=[TextPrimitive(pose=_pose(x, y + LABEL_ABOVE, 0.0, z=0.3),
                                         text=robot, font_size=LABEL_SIZE, billboard=True,
                                         scale_invariant=False, color=WHITE)],
                    lines=[LinePrimitive(type=LinePrimitiveLineType.LineStrip, thickness=0.04,
                                         color=BLUE, points=[Point3(x=a, y=b, z=0.02) for a, b
                                                             in self.trails.get(robot, ())]),
                           LinePrimitive(type=LinePrimitiveLineType.LineList, thickness=0.02,
                                         color=ORANGE, points=beams)]))
            return SceneUpdate(entities=ents)

    def poses_now(self) -> dict[str, tuple[float, float, float]]:
        with self._lock:
            return dict(self.poses)


def derived_channels(robots: list[str]) -> list[tuple[str, tuple[str, str, bytes], str]]:
    """(topic, schema, message encoding) of every channel FoxgloveOutputs emits for `robots`:
    what a live server advertises before the first frame."""
    out = [("/world", _schema(SceneUpdate), "protobuf"),
           ("/supervisor/state", SUPERVISOR_SNAPSHOT_SCHEMA, "json"),
           ("/supervisor/alarms", _schema(Log), "protobuf")]
    for robot in robots:
        out += [(f"/robots/{robot}/pose", _schema(PoseInFrame), "protobuf"),
                (f"/robots/{robot}/task", ROBOT_TASK_SCHEMA, "json")]
    return out


def _without_nulls(value):
    """A JSON value with every null member of a map left out (see _NUMBER); a snapshot is a
    few kilobytes, twice a simulated second."""
    if isinstance(value, dict):
        return {k: _without_nulls(v) for k, v in value.items() if v is not None}
    if isinstance(value, (list, tuple)):
        return [_without_nulls(v) for v in value]
    return value


class FoxgloveOutputs:
    """Turns bus samples and supervisor snapshots into the channels above, through `emit`."""

    def __init__(self, emit: Emit, robots: list[str] | None = None):
        self.emit = emit
        self.scene = Scene(robots)
        self._alarms: set[tuple[str, str]] = set()
        self._first_scene: int | None = None  # log time of the first scene frame asked for

    def on_sample(self, key: str, message) -> None:
        if key == "world" or key.endswith(("/ground_truth", "/sonar")):
            self.scene.on_sample(key, message)

    def frame(self, t_ns: int, snapshot: dict | None) -> None:
        """One refresh: the scene and poses; with a snapshot, the supervisor's channels."""
        self.scene_frame(t_ns)
        if snapshot is not None:
            self.supervisor_frame(t_ns, snapshot)

    def scene_frame(self, t_ns: int) -> None:
        """`/world` and every robot's pose, as the bus has them now, at log time `t_ns`. The
        first frames wait for the world's walls (up to WALLS_WAIT_NS of log time: a world
        may have none), so a viewer's first `/world` frame is never an empty floor."""
        if self._first_scene is None:
            self._first_scene = t_ns
        if not self.scene.walls and t_ns - self._first_scene < WALLS_WAIT_NS:
            return
        self.emit("/world", _schema(SceneUpdate), "protobuf", self.scene.update().encode(), t_ns)
        for robot, (x, y, th) in self.scene.poses_now().items():
            msg = PoseInFrame(timestamp=_stamp(t_ns), frame_id="world", pose=_pose(x, y, th))
            self.emit(f"/robots/{robot}/pose", _schema(PoseInFrame), "protobuf", msg.encode(),
                      t_ns)

    def supervisor_frame(self, t_ns: int, snapshot: dict) -> None:
        """`/supervisor/state`, every robot's `/robots/<id>/task`, and `/supervisor/alarms`
        for the alarms raised or cleared since the last frame."""
        self.emit("/supervisor/state", SUPERVISOR_SNAPSHOT_SCHEMA, "json",
                  to_json(_without_nulls(snapshot)).encode(), t_ns)
        for r in snapshot["robots"]:
            activity = r["task"] if r["state"] == "busy" and r["task"] else r["state"]
            self.emit(f"/robots/{r['id']}/task", ROBOT_TASK_SCHEMA, "json",
                      json.dumps({"state": r["state"], "task": r["task"] or "-",
                                  "activity": activity}).encode(), t_ns)
        alarms = {(a["kind"], a["subject"]) for a in snapshot["alarms"]}
        for kind, subject in sorted(alarms - self._alarms):
            self._log(t_ns, LogLevel.Warning, f"ALARM {kind} {subject}")
        for kind, subject in sorted(self._alarms - alarms):
            self._log(t_ns, LogLevel.Info, f"cleared {kind} {subject}")
        self._alarms = alarms

    def _log(self, t_ns: int, level, text: str) -> None:
        msg = Log(timestamp=_stamp(t_ns), level=level, message=text, name="supervisor")
        self.emit("/supervisor/alarms", _schema(Log), "protobuf", msg.encode(), t_ns)
