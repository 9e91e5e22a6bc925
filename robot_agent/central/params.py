"""central's parameter files, read as strictly as ALLIANCE's and MURDOCH's (a missing or unknown
key, a non-positive period, a sensor the robot lacks: a ConfigError naming file, line and key).

* Robot file (`robotN_central_params.yaml`): its loop rates, how often it reports, its lease on
  the dispatcher's word, the sensor its pose comes from, its sensors, and one entry per task it
  can serve (the evaluator saying whether it can serve it now).
* Tasks file (`tasks_central_params.yaml`): each task's id, name and layers (ALLIANCE's).
* Dispatcher file (`dispatcher_central_params.yaml`): the objective, its loop rate, how often it
  repeats the queues, the progress timeout, and the solver's limits.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

from mrta_zenoh.planning.schedule import Objective
from mrta_zenoh.yamlfile import YamlDoc, did_you_mean, load_yaml
from mrta_agent.runtime.params import (SensorParams, StrictMapping, TaskParams, iter_tasks,
                                       load_layers_params, open_robot_file,
                                       require_task)
from mrta_agent.runtime.plugins import EvaluatorSpec
from mrta_agent.route.executor import route_tasks

# A robot reports at least this often (s): its heartbeat to the dispatcher, and how fresh the
# supervisor's view of it is.
REPORT_PERIOD = 1.0
# A robot whose dispatcher is alive (its token lives) but silent for this long (s) stops where
# it is: a dispatcher cut off from it may have given its tasks to others (docs/central.md,
# "No task served twice"). Repeated queues (every resend_period) keep it going meanwhile.
LEASE = 3.0
# The dispatcher counts a robot stalled — alive, talking, not progressing — after this long
# (s) without progress on its task (it moved, turned, or its task changed), beyond the task's
# service time once it is there; and lost when it has not reported for as long.
PROGRESS_TIMEOUT = 10.0
RESEND_PERIOD = 1.0
EXACT_LIMIT = 8        # tasks still open up to which the dispatcher solves exactly
SOLUTIONS = 200        # the routing search's deterministic budget above it
TIME_LIMIT = 10.0      # its safety cap (s): a search stopped by it is not reproducible


@dataclass(frozen=True)
class RobotParams:
    name: str
    spin_rate: float
    control_rate: float
    report_period: float
    lease: float
    pose_topic: str | None
    sensors: tuple[SensorParams, ...]
    evaluators: tuple[EvaluatorSpec, ...]


@dataclass
class CentralParams:
    robot: RobotParams
    tasks: dict[str, TaskParams]
    layers: YamlDoc | None = None
    warnings: list[str] = field(default_factory=list)


@dataclass(frozen=True)
class DispatcherParams:
    objective: Objective = Objective.MINSUM
    spin_rate: float = 10.0
    resend_period: float = RESEND_PERIOD
    progress_timeout: float = PROGRESS_TIMEOUT
    exact_limit: int = EXACT_LIMIT
    solutions: int = SOLUTIONS
    time_limit: float = TIME_LIMIT

    def __post_init__(self) -> None:
        object.__setattr__(self, "objective", Objective(self.objective))  # "minsum" as well


ROBOT_KEYS = {"name", "spin_rate", "control_rate", "report_period", "lease", "pose_topic",
              "sensors", "tasks"}
DISPATCHER_KEYS = {"objective", "spin_rate", "resend_period", "progress_timeout", "exact_limit",
                   "solutions", "time_limit"}


def load_robot(path: Path | str) -> RobotParams:
    doc, top, sensors = open_robot_file(path, ROBOT_KEYS, "a central robot parameter file")
    evaluators, pose_topic = route_tasks(doc, top, sensors)
    robot = RobotParams(name=top.get("name", str, ""), spin_rate=top.rate("spin_rate", 10.0),
                        control_rate=top.rate("control_rate", 10.0),
                        report_period=top.duration("report_period", REPORT_PERIOD),
                        lease=top.duration("lease", LEASE), pose_topic=pose_topic,
                        sensors=sensors, evaluators=evaluators)
    if robot.lease <= 1.0 / robot.spin_rate:
        raise doc.error(("lease",), f"lease {robot.lease:g} s is not longer than a tick "
                        f"(1/spin_rate = {1.0 / robot.spin_rate:g} s): the robot would hold "
                        "between two of its own ticks")
    return robot


def load_params(robot_file, tasks_file, layers_file=None) -> CentralParams:
    robot = load_robot(robot_file)
    tasks = {t.id: t for _, t in iter_tasks(tasks_file)}
    for ev in robot.evaluators:
        require_task(ev.task_id, tasks, robot_file, "a task entry")
    return CentralParams(robot, tasks, load_layers_params(layers_file))


def load_dispatcher(path: Path | str) -> DispatcherParams:
    doc = load_yaml(path)
    if not isinstance(doc.data, dict):
        raise doc.error((), "a dispatcher parameter file must be a mapping")
    top = StrictMapping(doc, (), DISPATCHER_KEYS)
    name = top.get("objective", str, Objective.MINSUM.value)
    try:
        objective = Objective(name)
    except ValueError:
        known = [o.value for o in Objective]
        raise doc.error(("objective",), f"objective {name!r} is not one of "
                        f"{', '.join(known)}" + did_you_mean(name, known)) from None
    ints = {}
    for key, default in (("exact_limit", EXACT_LIMIT), ("solutions", SOLUTIONS)):
        value = top.data.get(key, default)
        if type(value) is not int or not 0 <= value <= 10_000:
            raise doc.error((key,), f"{key} must be a whole number in [0, 10000], got "
                            f"{value!r:.40}")
        ints[key] = value
    if ints["exact_limit"] > 12:
        raise doc.error(("exact_limit",), f"exact_limit {ints['exact_limit']} is more than 12 "
                        "tasks: the exact recursion grows as robots · 3ⁿ (docs/delivery.md)")
    if ints["solutions"] < 1:
        raise doc.error(("solutions",), "solutions must be at least 1")
    params = DispatcherParams(objective, top.rate("spin_rate", 10.0),
                              top.duration("resend_period", RESEND_PERIOD),
                              top.duration("progress_timeout", PROGRESS_TIMEOUT),
                              ints["exact_limit"], ints["solutions"],
                              top.duration("time_limit", TIME_LIMIT))
    return params

