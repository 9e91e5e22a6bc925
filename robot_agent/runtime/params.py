"""What every architecture's parameter files share: the robot file's sensors, the tasks file
(ids, names, layer stacks) and the layers file the plugins read, as typed documents
(mrta_zenoh.paramdoc: unknown keys refused with "did you mean", numbers finite, rates and
durations in range, rqt_mrta's sized arrays read as lists).

Strict: a missing mandatory key or an unknown key is a ConfigError naming file, line and key.
Each architecture's robot file is a Struct of its own (its params module) holding `sensors:
Sensors`; the tasks file is `TasksFile[TaskDoc]` (MURDOCH's adds keys to TaskDoc).
"""

from dataclasses import dataclass
from pathlib import Path
from typing import Generic, Iterator, NamedTuple, TypeVar

import msgspec

from mrta_zenoh import paramdoc
from mrta_zenoh.errors import ConfigError
from mrta_zenoh.paramdoc import Document, Duration, Id, Text, sized
from mrta_zenoh.shared_reads import once
from mrta_zenoh.yamlfile import YamlDoc, did_you_mean, load_yaml

from .instance import KEY as INSTANCE_KEY


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
    name: Text = ""  # the id when absent
    layers: sized(LayerDoc, "layer") = []


TaskT = TypeVar("TaskT", bound=TaskDoc)


class TasksFile(Doc, Generic[TaskT]):
    tasks: sized(TaskT, "task")


Sensors = sized(SensorDoc, "sensor")
Topics = sized(TopicDoc, "sensor")


class EvaluatorSpec(NamedTuple):
    """One task's sensory evaluator: which plugin, on which of the robot's sensors."""

    task_id: str
    plugin_name: str
    topics: tuple[str, ...]
    where: str = ""


class EvaluatorDoc(Doc):
    """A sensory evaluator as a robot file names it (ALLIANCE's `sensory_feedback`, MURDOCH's
    `progress`, the route family's `evaluator`): its plugin and the robot's sensors it reads."""

    plugin_name: Text
    sensors: Topics


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


def evaluator_spec(d: Document, path: tuple, task_id: str, ev: EvaluatorDoc,
                   robot: tuple[SensorParams, ...]) -> EvaluatorSpec:
    """The evaluator at `path` of the robot file, its sensors checked against the robot's."""
    return EvaluatorSpec(task_id, ev.plugin_name,
                         sensor_topics(d, path + ("sensors",), ev.sensors, robot),
                         d.where(path + ("plugin_name",)))


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
    """The tasks file's TaskParams by id: a dict of the caller's own (a robot may grow its
    tasks), of frozen entries read once per agent host (mrta_zenoh.shared_reads)."""
    return dict(once(path, "tasks", lambda: {t.id: t for *_, t in read_tasks(path)}))


def load_layers_params(path: Path | str | None) -> YamlDoc | None:
    """The layers file: a mapping of sections, each a mapping (its keys are checked by the
    plugins' typed parameters once the plugins are known), and the `instance` file it names
    (runtime.instance)."""
    if path is None:
        return None
    return once(path, "layers", lambda: _layers_doc(path))


def _layers_doc(path: Path | str) -> YamlDoc:
    doc = load_yaml(path)
    if not isinstance(doc.data, dict):
        raise doc.error((), "a layers parameter file must be a mapping of layer sections")
    for name, section in doc.data.items():
        if name == INSTANCE_KEY:  # the instance file it names, not a section
            continue
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

