"""What every architecture's parameter files share: the robot file's sensors, the tasks file
(ids, names, layer stacks) and the layers file the plugins read, as typed documents
(mrta_zenoh.paramdoc: unknown keys refused with "did you mean", numbers finite, rates and
durations in range, rqt_mrta's sized arrays read as lists).

Strict: a missing mandatory key or an unknown key is a ConfigError naming file, line and key.
Each architecture's robot file is a Struct of its own (its params module) holding `sensors:
Sensors`; the tasks file is `TasksFile[TaskDoc]` (MURDOCH's adds keys to TaskDoc).
"""

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Generic, Iterator, TypeVar

import msgspec

from mrta_zenoh import paramdoc
from mrta_zenoh.errors import ConfigError
from mrta_zenoh.keys import is_id
from mrta_zenoh.limits import DURATION, RATE, Range
from mrta_zenoh.paramdoc import Document, Duration, Id, Text, sized
from mrta_zenoh.yamlfile import YamlDoc, did_you_mean, get_path, load_yaml, sized_array


NUMBER = (int, float)


@dataclass(frozen=True)
class SensorParams:
    plugin_name: str
    topic_name: str
    timeout_duration: float = 5.0
    buffer_horizon: float = 5.0
    where: str = ""  # file:line of plugin_name, for errors about the plugin


@dataclass(frozen=True)
class TaskParams:
    id: str
    name: str
    layers: tuple[str, ...]
    where: tuple[str, ...] = ()  # file:line of each layer's plugin_name


class Doc(msgspec.Struct, forbid_unknown_fields=True, frozen=True):
    """The base of every parameter document: no key beyond its fields."""


class SensorDoc(Doc):
    plugin_name: Text
    topic_name: Text
    timeout_duration: Duration = 5.0
    buffer_horizon: Duration = 5.0


class TopicDoc(Doc):
    """One of the robot's sensors, named by topic (an evaluator's inputs, a task's resources)."""
    topic_name: Text


class LayerDoc(Doc):
    plugin_name: Text


class TaskDoc(Doc):
    id: Id
    name: Text | None = None  # the id when absent
    layers: sized(LayerDoc, "layer") = []


TaskT = TypeVar("TaskT", bound=TaskDoc)


class TasksFile(Doc, Generic[TaskT]):
    tasks: sized(TaskT, "task")


Sensors = sized(SensorDoc, "sensor")
Topics = sized(TopicDoc, "sensor")


def sensor_params(d: Document, sensors: list[SensorDoc]) -> tuple[SensorParams, ...]:
    """The robot file's `sensors` (every architecture's robot file has them at the top)."""
    return tuple(SensorParams(s.plugin_name, s.topic_name, s.timeout_duration, s.buffer_horizon,
                              d.where(("sensors", i, "plugin_name")))
                 for i, s in enumerate(sensors))


def sensor_topics(d: Document, path: tuple, topics: list[TopicDoc],
                  robot: tuple[SensorParams, ...]) -> tuple[str, ...]:
    """An evaluator's `sensors` at `path`: topic names, each one of the robot's sensors."""
    known = {s.topic_name for s in robot}
    for i, t in enumerate(topics):
        if t.topic_name not in known:
            raise d.error(path + (i, "topic_name"), f"sensor topic {t.topic_name!r} is not among "
                          f"the robot's sensors ({', '.join(sorted(known)) or 'none'})"
                          + did_you_mean(t.topic_name, known))
    return tuple(t.topic_name for t in topics)


def pose_topic_of(d: Document, pose_topic: str | None, robot: tuple[SensorParams, ...]
                  ) -> str | None:
    """The robot file's `pose_topic`, one of its sensors (or none)."""
    known = {s.topic_name for s in robot}
    if pose_topic is not None and pose_topic not in known:
        raise d.error(("pose_topic",), f"pose_topic {pose_topic!r} is not among the robot's "
                      f"sensors ({', '.join(sorted(known)) or 'none'})"
                      + did_you_mean(pose_topic, known))
    return pose_topic


def read_tasks(path: Path | str, kind: type[TaskT] = TaskDoc
               ) -> Iterator[tuple[Document, int, TaskT, TaskParams]]:
    """Each task of a tasks file (every architecture's) as `kind` — TaskDoc, or an
    architecture's subclass with keys of its own — with its document, its index and its
    TaskParams. Ids must be unique."""
    d = paramdoc.load(path, TasksFile[kind], "a tasks parameter file")
    seen: set[str] = set()
    for i, t in enumerate(d.value.tasks):
        if t.id in seen:
            raise d.error(("tasks", i, "id"), f"task id {t.id!r} appears twice")
        seen.add(t.id)
        where = tuple(d.where(("tasks", i, "layers", j, "plugin_name"))
                      for j in range(len(t.layers)))
        yield d, i, t, TaskParams(t.id, t.name or t.id,
                                  tuple(layer.plugin_name for layer in t.layers), where)


def load_tasks_params(path: Path | str) -> dict[str, TaskParams]:
    return {t.id: t for *_, t in read_tasks(path)}


class StrictMapping:
    """Reads one mapping, remembering which keys were used, so leftovers can be reported."""

    def __init__(self, doc: YamlDoc, path: tuple, allowed: set[str]):
        self.doc, self.path = doc, path
        data = get_path(doc.data, path)
        if not isinstance(data, dict):
            raise doc.error(path, "expected a mapping")
        self.data = data
        unknown = [k for k in data if k not in allowed]
        if unknown:
            k = unknown[0]
            raise doc.error(path + (k,), f"unknown key {k!r}" + did_you_mean(k, allowed))

    def get(self, key: str, kind, default: Any = ..., positive: bool = False,
            within: Range | None = None) -> Any:
        """The value of `key` as `kind`; a number is finite, > 0 with `positive`, and inside
        `within` (mrta_zenoh.limits): the error names file, line, key and the range."""
        if key not in self.data:
            if default is ...:
                raise self.doc.error(self.path + (key,), f"missing mandatory key {key!r}")
            return default
        value = self.data[key]
        if kind is float:
            if type(value) is bool or not isinstance(value, NUMBER):
                raise self.doc.error(self.path + (key,), f"{key} must be a number, got {value!r:.40}")
            value = float(value)
            if not math.isfinite(value):
                raise self.doc.error(self.path + (key,), f"{key} must be a finite number, got {value}")
            if positive and value <= 0:
                raise self.doc.error(self.path + (key,), f"{key} must be > 0, got {value:g}")
            if within is not None and within.problem(value):
                raise self.doc.error(self.path + (key,), f"{key} {within.problem(value)}")
        elif kind is str:
            if not isinstance(value, str) or not value.strip():
                raise self.doc.error(self.path + (key,), f"{key} must be a non-empty string, got {value!r:.40}")
        return value

    def rate(self, key: str, default: Any = ...) -> float:
        """A frequency in Hz: positive, finite, and within what a process can honour."""
        return self.get(key, float, default, positive=True, within=RATE)

    def duration(self, key: str, default: Any = ...) -> float:
        """A duration, delay or timeout in seconds: positive, finite, at most a day."""
        return self.get(key, float, default, positive=True, within=DURATION)

    def where(self, key: str) -> str:
        line = self.doc.line(self.path + (key,))
        return f"{self.doc.path}:{line}" if line else str(self.doc.path)


def load_sensors(doc: YamlDoc) -> tuple[SensorParams, ...]:
    """The robot file's `sensors` array (shared by every architecture's robot file)."""
    sensors = []
    for spath, _ in sized_array(doc, ("sensors",), "sensor"):
        r = StrictMapping(doc, spath, {"plugin_name", "topic_name", "timeout_duration", "buffer_horizon"})
        sensors.append(SensorParams(
            plugin_name=r.get("plugin_name", str), topic_name=r.get("topic_name", str),
            timeout_duration=r.duration("timeout_duration", 5.0),
            buffer_horizon=r.duration("buffer_horizon", 5.0),
            where=r.where("plugin_name")))
    return tuple(sensors)


def load_sensor_topics(doc: YamlDoc, path: tuple, topics: set[str]) -> tuple[str, ...]:
    """An evaluator's `sensors` array: topic names, each one of the robot's sensors."""
    out = []
    for fp, _ in sized_array(doc, path, "sensor"):
        t = StrictMapping(doc, fp, {"topic_name"}).get("topic_name", str)
        if t not in topics:
            raise doc.error(fp + ("topic_name",), f"sensor topic {t!r} is not among the robot's "
                            f"sensors ({', '.join(sorted(topics)) or 'none'})" + did_you_mean(t, topics))
        out.append(t)
    return tuple(out)


def task_id_of(m: StrictMapping, key: str) -> str:
    """The task id under `key` of a mapping: one key chunk, or a ConfigError naming the key."""
    task_id = m.get(key, str)
    if not is_id(task_id):
        raise m.doc.error(m.path + (key,), f"task id {task_id!r:.80} must be one key chunk: "
                          "up to 64 letters, digits, '_', '-' or '.'")
    return task_id


def open_robot_file(path: Path | str, keys: set[str], what: str
                    ) -> tuple[YamlDoc, StrictMapping, tuple[SensorParams, ...]]:
    """A robot parameter file (every architecture's): its document, its top-level keys
    checked against `keys`, and its sensors."""
    doc = load_yaml(path)
    if not isinstance(doc.data, dict):
        raise doc.error((), f"{what} must be a mapping")
    return doc, StrictMapping(doc, (), keys), load_sensors(doc)


def iter_tasks(path: Path | str, extra_keys: frozenset[str] = frozenset()
               ) -> Iterator[tuple[StrictMapping, TaskParams]]:
    """Each task of a tasks file (every architecture's): its mapping — with `extra_keys` allowed
    beside id, name and layers, for the architecture to read — and its TaskParams. Ids are
    checked and must be unique."""
    doc = load_yaml(path)
    if not isinstance(doc.data, dict):
        raise doc.error((), "a tasks parameter file must be a mapping")
    StrictMapping(doc, (), {"tasks"})
    seen: set[str] = set()
    for tpath, _ in sized_array(doc, ("tasks",), "task"):
        r = StrictMapping(doc, tpath, {"id", "name", "layers"} | extra_keys)
        task_id = task_id_of(r, "id")
        if task_id in seen:
            raise doc.error(tpath + ("id",), f"task id {task_id!r} appears twice")
        seen.add(task_id)
        layers, where = [], []
        if "layers" in r.data:
            for lpath, _ in sized_array(doc, tpath + ("layers",), "layer"):
                lr = StrictMapping(doc, lpath, {"plugin_name"})
                layers.append(lr.get("plugin_name", str))
                where.append(lr.where("plugin_name"))
        yield r, TaskParams(task_id, r.get("name", str, task_id), tuple(layers), tuple(where))


def load_layers_params(path: Path | str | None) -> YamlDoc | None:
    """The layers file: a mapping of sections, each a mapping (its keys are checked by the
    plugins' typed parameters once the plugins are known)."""
    if path is None:
        return None
    doc = load_yaml(path)
    if not isinstance(doc.data, dict):
        raise doc.error((), "a layers parameter file must be a mapping of layer sections")
    for name, section in doc.data.items():
        if not isinstance(section, dict):
            raise doc.error((name,), f"section {name!r} must be a mapping of parameters, "
                            f"got {type(section).__name__}")
    return doc


def require_task(task_id: str, tasks, robot_file, what: str) -> None:
    """A robot file's `what` (behaviour set, skill) names a task the tasks file must have."""
    if task_id not in tasks:
        raise ConfigError(
            f"{what} for task {task_id!r} but the tasks file has "
            f"{', '.join(sorted(tasks)) or 'no tasks'}" + did_you_mean(task_id, tasks),
            file=str(robot_file), element="'task_id'")

