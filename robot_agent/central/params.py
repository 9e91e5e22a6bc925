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

import msgspec

from mrta_zenoh import paramdoc
from mrta_zenoh.planning.schedule import Objective
from mrta_zenoh.paramdoc import Duration, Rate, whole
from mrta_zenoh.yamlfile import YamlDoc
from mrta_agent.runtime.params import (Doc, EvaluatorSpec, SensorParams, TaskParams,
                                       load_layers_params, load_tasks_params, require_task,
                                       sensor_params)
from mrta_agent.route.executor import RouteRobotFile, route_tasks

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
SEARCH_LIMIT = 50      # open tasks up to which that search runs; above, cheapest insertion
TIME_LIMIT = 10.0      # its safety cap (CPU s of the search): one stopped by it is not reproducible


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


class DispatcherParams(Doc, kw_only=True):
    """The dispatcher file, as written and as the dispatcher reads it."""

    objective: Objective = Objective.MINSUM
    spin_rate: Rate = 10.0
    resend_period: Duration = RESEND_PERIOD
    progress_timeout: Duration = PROGRESS_TIMEOUT
    exact_limit: whole(0, 10_000) = EXACT_LIMIT
    solutions: whole(1, 10_000) = SOLUTIONS
    search_limit: whole(0, 100_000) = SEARCH_LIMIT
    time_limit: Duration = TIME_LIMIT

    def __post_init__(self) -> None:
        msgspec.structs.force_setattr(self, "objective", Objective(self.objective))  # "minsum"


class RobotFile(RouteRobotFile, kw_only=True):
    """A central robot file as written: the route family's keys and the lease."""

    lease: Duration = LEASE


def load_robot(path: Path | str) -> RobotParams:
    d = paramdoc.load(path, RobotFile, "a central robot parameter file")
    f = d.value
    sensors = sensor_params(d, f.sensors)
    evaluators, pose_topic = route_tasks(d, f, sensors)
    robot = RobotParams(name=f.name, spin_rate=f.spin_rate, control_rate=f.control_rate,
                        report_period=f.report_period, lease=f.lease, pose_topic=pose_topic,
                        sensors=sensors, evaluators=evaluators)
    if robot.lease <= 1.0 / robot.spin_rate:
        raise d.error(("lease",), f"lease {robot.lease:g} s is not longer than a tick "
                      f"(1/spin_rate = {1.0 / robot.spin_rate:g} s): the robot would hold "
                      "between two of its own ticks")
    return robot


def load_params(robot_file, tasks_file, layers_file=None) -> CentralParams:
    robot = load_robot(robot_file)
    tasks = load_tasks_params(tasks_file)
    for ev in robot.evaluators:
        require_task(ev.task_id, tasks, robot_file, "a task entry")
    return CentralParams(robot, tasks, load_layers_params(layers_file))


def load_dispatcher(path: Path | str) -> DispatcherParams:
    d = paramdoc.load(path, DispatcherParams, "a dispatcher parameter file")
    if d.value.exact_limit > 12:
        raise d.error(("exact_limit",), f"exact_limit {d.value.exact_limit} is more than 12 "
                      "tasks: the exact recursion grows as robots · 3ⁿ (docs/delivery.md)")
    return d.value
