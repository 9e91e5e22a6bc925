"""The parameter files of a robot serving its own route (SSI, CBBA), read as strictly as
central's (a missing or unknown key, a non-positive period, a sensor the robot lacks: a
ConfigError naming file, line and key).

Robot file (`robotN_<arch>_params.yaml`): its loop rates, how often it reports, the progress
timeout after which a teammate that makes no progress counts as gone, the sensor its pose comes
from, the instance its decision logic plans on (a path relative to the file: every robot must
read the same instance), its sensors, one entry per task it can serve (the evaluator saying
whether it can serve it now) — and the architecture's own keys (`extra`). Tasks file: each
task's id, name and layers.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import msgspec

from mrta_zenoh import instances, paramdoc
from mrta_zenoh.errors import ConfigError
from mrta_zenoh.paramdoc import Duration, Text
from mrta_zenoh.planning import Problem
from mrta_zenoh.shared_reads import once
from mrta_zenoh.yamlfile import YamlDoc, did_you_mean

from ..runtime.instance import same_instance
from ..runtime.params import (EvaluatorSpec, SensorParams, TaskParams, load_layers_params,
                              load_tasks_params, require_task, sensor_params)
from .executor import RouteRobotFile, route_tasks

# A teammate whose reports show a task but no progress (no motion, nothing served, no change of
# task) for this long (s) counts as gone: its tasks go to the others. Longer than any task's
# service in the shipped applications, so a robot serving in place is not taken for stalled.
PROGRESS_TIMEOUT = 10.0


class OwnRouteFile(RouteRobotFile, kw_only=True):
    """The keys every own-route robot file has: the route family's, the instance (relative to
    the file) and the progress timeout."""

    instance: Text
    progress_timeout: Duration = PROGRESS_TIMEOUT


@functools.cache
def robot_file(keys: type) -> type:
    """An own-route architecture's robot file: OwnRouteFile's keys and those of `keys`, the
    Struct of the architecture's own (SsiKeys, CbbaKeys: their defaults and bounds)."""
    fields = [(f.name, f.type, f.default if f.default is not msgspec.NODEFAULT
               else msgspec.field(default_factory=f.default_factory))
              for f in msgspec.structs.fields(keys)]
    return msgspec.defstruct(keys.__name__.removesuffix("Keys") + "RobotFile", fields,
                             bases=(OwnRouteFile,), kw_only=True, module=keys.__module__)


@dataclass(frozen=True)
class OwnRouteRobot:
    name: str
    spin_rate: float
    control_rate: float
    report_period: float
    progress_timeout: float
    pose_topic: str | None
    instance: Path
    sensors: tuple[SensorParams, ...]
    evaluators: tuple[EvaluatorSpec, ...]
    extra: Any = None  # the architecture's own keys: its Struct (SsiKeys, CbbaKeys)


@dataclass
class OwnRouteParams:
    robot: OwnRouteRobot
    problem: Problem
    tasks: dict[str, TaskParams]
    layers: YamlDoc | None = None
    warnings: list[str] = field(default_factory=list)
    instance: instances.Loaded | None = None  # what `problem` came from, read once


def load_robot(path: Path | str, what: str, keys: type) -> OwnRouteRobot:
    d = paramdoc.load(path, robot_file(keys), what)
    f = d.value
    sensors = sensor_params(d, f.sensors)
    evaluators, pose_topic = route_tasks(d, f, sensors)
    return OwnRouteRobot(
        name=f.name, spin_rate=f.spin_rate, control_rate=f.control_rate,
        report_period=f.report_period, progress_timeout=f.progress_timeout,
        pose_topic=pose_topic, instance=Path(d.doc.path).parent / f.instance, sensors=sensors,
        evaluators=evaluators,
        extra=keys(**{name: getattr(f, name) for name in keys.__struct_fields__}))


def load_files(robot_file, tasks_file, what: str, keys: type
               ) -> tuple[OwnRouteRobot, dict[str, TaskParams]]:
    """The robot and tasks files, checked against each other — not the instance they name,
    which an application writes beside them (`mrta app new` does not: the check of what it
    writes stops here)."""
    robot = load_robot(robot_file, what, keys)
    tasks = load_tasks_params(tasks_file)
    for ev in robot.evaluators:
        require_task(ev.task_id, tasks, robot_file, "a task entry")
    return robot, tasks


def load_params(robot_id: str, robot_file, tasks_file, layers_file, what: str, keys: type
                ) -> OwnRouteParams:
    robot, tasks = load_files(robot_file, tasks_file, what, keys)
    if not robot.instance.is_file():
        raise ConfigError(f"{robot_file}: its instance file {robot.instance} does not exist "
                          "(the key `instance`, relative to the robot file)")
    layers = load_layers_params(layers_file)
    same_instance(robot.instance, layers, robot_file)
    loaded = instances.load(robot.instance)  # once: the plugins read the same (`instance`)
    # frozen, and its travel matrix (robots + tasks)² floats: one per agent host (shared_reads)
    problem = once(robot.instance, "problem", lambda: loaded.kind.problem(loaded.doc))
    if not isinstance(problem, Problem):
        raise ConfigError(f"{robot.instance}: its instance kind gave a "
                          f"{type(problem).__name__}, not a mrta_zenoh.planning.Problem")
    ids = [r.id for r in problem.robots]
    if robot_id not in ids:
        raise ConfigError(f"{robot_file}: robot {robot_id} is not in its instance "
                          f"{robot.instance} ({', '.join(ids)})" + did_you_mean(robot_id, ids))
    return OwnRouteParams(robot, problem, tasks, layers, instance=loaded)
