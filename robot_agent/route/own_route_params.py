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

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable

from mrta_zenoh import instances
from mrta_zenoh.errors import ConfigError
from mrta_zenoh.planning import Problem
from mrta_zenoh.yamlfile import YamlDoc, did_you_mean

from ..runtime.params import (SensorParams, StrictMapping, TaskParams, iter_tasks, load_layers_params,
                     open_robot_file, require_task)
from ..runtime.plugins import EvaluatorSpec
from .executor import route_tasks

REPORT_PERIOD = 1.0
# A teammate whose reports show a task but no progress (no motion, nothing served, no change of
# task) for this long (s) counts as gone: its tasks go to the others. Longer than any task's
# service in the shipped applications, so a robot serving in place is not taken for stalled.
PROGRESS_TIMEOUT = 10.0

COMMON_KEYS = {"name", "spin_rate", "control_rate", "report_period", "progress_timeout",
               "pose_topic", "instance", "sensors", "tasks"}


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
    extra: Any = None  # the architecture's own keys, as its reader returned them


@dataclass
class OwnRouteParams:
    robot: OwnRouteRobot
    problem: Problem
    tasks: dict[str, TaskParams]
    layers: YamlDoc | None = None
    warnings: list[str] = field(default_factory=list)


def lookahead(top: StrictMapping) -> float:
    """The `lookahead` key (s, 0 by default): how long before its arrival a task is planned."""
    value = top.get("lookahead", float, 0.0)
    if value < 0:
        raise top.doc.error(("lookahead",), f"lookahead must be ≥ 0, got {value:g}")
    return value


def load_robot(path: Path | str, what: str, extra_keys: set[str],
               read_extra: Callable[[StrictMapping], Any]) -> OwnRouteRobot:
    doc, top, sensors = open_robot_file(path, COMMON_KEYS | extra_keys, what)
    evaluators, pose_topic = route_tasks(doc, top, sensors)
    instance = Path(doc.path).parent / top.get("instance", str)
    return OwnRouteRobot(
        name=top.get("name", str, ""), spin_rate=top.rate("spin_rate", 10.0),
        control_rate=top.rate("control_rate", 10.0),
        report_period=top.duration("report_period", REPORT_PERIOD),
        progress_timeout=top.duration("progress_timeout", PROGRESS_TIMEOUT),
        pose_topic=pose_topic, instance=instance, sensors=sensors,
        evaluators=evaluators, extra=read_extra(top))


def load_files(robot_file, tasks_file, what: str, extra_keys: set[str],
               read_extra: Callable[[StrictMapping], Any]
               ) -> tuple[OwnRouteRobot, dict[str, TaskParams]]:
    """The robot and tasks files, checked against each other — not the instance they name,
    which an application writes beside them (`mrta app new` does not: the check of what it
    writes stops here)."""
    robot = load_robot(robot_file, what, extra_keys, read_extra)
    tasks = {t.id: t for _, t in iter_tasks(tasks_file)}
    for ev in robot.evaluators:
        require_task(ev.task_id, tasks, robot_file, "a task entry")
    return robot, tasks


def load_params(robot_id: str, robot_file, tasks_file, layers_file, what: str,
                extra_keys: set[str], read_extra: Callable[[StrictMapping], Any]
                ) -> OwnRouteParams:
    robot, tasks = load_files(robot_file, tasks_file, what, extra_keys, read_extra)
    if not robot.instance.is_file():
        raise ConfigError(f"{robot_file}: its instance file {robot.instance} does not exist "
                          "(the key `instance`, relative to the robot file)")
    problem = instances.problem(robot.instance)
    if not isinstance(problem, Problem):
        raise ConfigError(f"{robot.instance}: its instance kind gave a "
                          f"{type(problem).__name__}, not a mrta_zenoh.planning.Problem")
    ids = [r.id for r in problem.robots]
    if robot_id not in ids:
        raise ConfigError(f"{robot_file}: robot {robot_id} is not in its instance "
                          f"{robot.instance} ({', '.join(ids)})" + did_you_mean(robot_id, ids))
    return OwnRouteParams(robot, problem, tasks, load_layers_params(layers_file))
