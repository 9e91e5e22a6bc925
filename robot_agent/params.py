"""ALLIANCE parameters in the dissertation's YAML layout (the reference files load unchanged).

Strict: a missing mandatory key, a non-positive rate or τ, or an unknown key in the robot or tasks
file is a ConfigError naming file, line and key (with "did you mean"). The layers file belongs to
the layer plugins, so it is only required to be a mapping. Legal but suspicious values are
returned as warnings naming file and key.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Iterator

from mrta_zenoh.errors import ConfigError
from mrta_zenoh.keys import is_id
from mrta_zenoh.yamlfile import YamlDoc, did_you_mean, get_path, load_yaml, sized_array

NUMBER = (int, float)
MIN_RATE, MAX_RATE = 0.01, 1000.0  # Hz: below, a tick a minute and a half; above, a busy loop


@dataclass(frozen=True)
class SensorParams:
    plugin_name: str
    topic_name: str
    timeout_duration: float = 5.0
    buffer_horizon: float = 5.0
    where: str = ""  # file:line of plugin_name, for errors about the plugin


@dataclass(frozen=True)
class BehaviourSetParams:
    task_id: str
    expected_duration: float
    threshold: float
    yielding_delay: float
    giving_up_delay: float
    fast_rate: float
    evaluator_plugin: str
    evaluator_topics: tuple[str, ...]
    where: str = ""  # file:line of the evaluator's plugin_name


@dataclass(frozen=True)
class RobotParams:
    name: str
    spin_rate: float
    broadcast_rate: float
    timeout_duration: float
    buffer_horizon: float
    sensors: tuple[SensorParams, ...]
    behaviour_sets: tuple[BehaviourSetParams, ...]
    control_rate: float = 10.0
    max_expected_duration: float = 3600.0  # broadcasts announcing more are refused


@dataclass(frozen=True)
class TaskParams:
    id: str
    name: str
    layers: tuple[str, ...]
    where: tuple[str, ...] = ()  # file:line of each layer's plugin_name


@dataclass
class AgentParams:
    robot: RobotParams
    tasks: dict[str, TaskParams]
    layers: YamlDoc | None = None  # the layers file; plugins' typed sections are read from it
    warnings: list[str] = field(default_factory=list)


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

    def get(self, key: str, kind, default: Any = ..., positive: bool = False) -> Any:
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
        elif kind is str:
            if not isinstance(value, str) or not value.strip():
                raise self.doc.error(self.path + (key,), f"{key} must be a non-empty string, got {value!r:.40}")
        return value

    def rate(self, key: str, default: Any = ...) -> float:
        """A frequency in Hz: positive, finite, and within what a process can honour."""
        value = self.get(key, float, default, positive=True)
        if not MIN_RATE <= value <= MAX_RATE:
            raise self.doc.error(self.path + (key,), f"{key} must be between {MIN_RATE:g} and "
                                 f"{MAX_RATE:g} Hz, got {value:g}")
        return value

    def where(self, key: str) -> str:
        line = self.doc.line(self.path + (key,))
        return f"{self.doc.path}:{line}" if line else str(self.doc.path)


ROBOT_KEYS = {"name", "spin_rate", "broadcast_rate", "timeout_duration", "buffer_horizon",
              "sensors", "behaviour_sets", "control_rate", "id", "max_expected_duration"}


def load_sensors(doc: YamlDoc) -> tuple[SensorParams, ...]:
    """The robot file's `sensors` array (shared by every architecture's robot file)."""
    sensors = []
    for spath, _ in sized_array(doc, ("sensors",), "sensor"):
        r = StrictMapping(doc, spath, {"plugin_name", "topic_name", "timeout_duration", "buffer_horizon"})
        sensors.append(SensorParams(
            plugin_name=r.get("plugin_name", str), topic_name=r.get("topic_name", str),
            timeout_duration=r.get("timeout_duration", float, 5.0, positive=True),
            buffer_horizon=r.get("buffer_horizon", float, 5.0, positive=True),
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


def load_robot_params(path: Path | str) -> tuple[RobotParams, list[str]]:
    doc, top, sensors = open_robot_file(path, ROBOT_KEYS, "a robot parameter file")
    warnings: list[str] = []
    topics = {s.topic_name for s in sensors}
    sets = []
    seen_tasks: set[str] = set()
    for bpath, _ in sized_array(doc, ("behaviour_sets",), "behaviour_set"):
        b = StrictMapping(doc, bpath, {"task_id", "task_expected_duration", "motivational_behaviour"})
        mpath = bpath + ("motivational_behaviour",)
        m = StrictMapping(doc, mpath, {"threshold", "acquiescence", "impatience", "sensory_feedback"})
        a = StrictMapping(doc, mpath + ("acquiescence",), {"yielding_delay", "giving_up_delay"})
        i = StrictMapping(doc, mpath + ("impatience",), {"fast_rate"})
        f = StrictMapping(doc, mpath + ("sensory_feedback",), {"plugin_name", "sensors"})
        ftopics = load_sensor_topics(doc, mpath + ("sensory_feedback", "sensors"), topics)
        task_id = task_id_of(b, "task_id")
        if task_id in seen_tasks:
            raise doc.error(bpath + ("task_id",), f"task {task_id!r} has two behaviour sets")
        seen_tasks.add(task_id)
        bs = BehaviourSetParams(
            task_id=task_id,
            expected_duration=b.get("task_expected_duration", float, positive=True),
            threshold=m.get("threshold", float, positive=True),
            yielding_delay=a.get("yielding_delay", float, positive=True),
            giving_up_delay=a.get("giving_up_delay", float, positive=True),
            fast_rate=i.get("fast_rate", float, positive=True),
            evaluator_plugin=f.get("plugin_name", str),
            evaluator_topics=ftopics,
            where=f.where("plugin_name"),
        )
        if bs.yielding_delay > bs.giving_up_delay:
            warnings.append(doc.warning(
                a.path + ("yielding_delay",),
                f"yielding_delay {bs.yielding_delay:g} s is longer than giving_up_delay "
                f"{bs.giving_up_delay:g} s: this robot gives up before it would ever yield"))
        sets.append(bs)
    robot = RobotParams(
        name=top.get("name", str, ""),
        spin_rate=top.rate("spin_rate"),
        broadcast_rate=top.rate("broadcast_rate"),
        timeout_duration=top.get("timeout_duration", float, positive=True),
        buffer_horizon=top.get("buffer_horizon", float, 10.0, positive=True),
        sensors=sensors, behaviour_sets=tuple(sets),
        control_rate=top.rate("control_rate", 10.0),
        max_expected_duration=top.get("max_expected_duration", float, 3600.0, positive=True),
    )
    tick = 1.0 / robot.spin_rate
    if robot.timeout_duration <= tick:
        raise doc.error(("timeout_duration",), f"timeout_duration {robot.timeout_duration:g} s must "
                        f"be longer than the tick period 1/spin_rate = {tick:g} s, or a teammate "
                        "heard between two ticks is never seen")
    period = effective_broadcast_period(robot)
    if robot.timeout_duration < 2 * period:
        warnings.append(doc.warning(
            ("timeout_duration",),
            f"broadcasts leave on ticks, so every {period:g} s (broadcast_rate "
            f"{robot.broadcast_rate:g} Hz at spin_rate {robot.spin_rate:g} Hz); timeout_duration "
            f"{robot.timeout_duration:g} s is less than twice that: one late broadcast makes "
            "teammates think this robot stopped"))
    return robot, warnings


def effective_broadcast_period(robot: RobotParams) -> float:
    """Broadcasts go out on high-level ticks: the period is 1/broadcast_rate rounded up to ticks."""
    ticks = math.ceil(round(robot.spin_rate / robot.broadcast_rate, 9))
    return max(1, ticks) / robot.spin_rate


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


def load_tasks_params(path: Path | str) -> dict[str, TaskParams]:
    return {t.id: t for _, t in iter_tasks(path)}


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


def load_agent_params(robot_file, tasks_file, layers_file=None) -> AgentParams:
    robot, warnings = load_robot_params(robot_file)
    tasks = load_tasks_params(tasks_file)
    for bs in robot.behaviour_sets:
        require_task(bs.task_id, tasks, robot_file, "behaviour set")
    return AgentParams(robot, tasks, load_layers_params(layers_file), warnings)
