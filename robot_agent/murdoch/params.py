"""MURDOCH parameters, in the same YAML layout as ALLIANCE's (sized arrays, `sensors` as in the
ALLIANCE robot file), checked as strictly: a missing key, a non-positive period, a value outside
its sane range (mrta_zenoh.limits), an unknown key,
a sensor topic the robot lacks or a task the tasks file lacks is a ConfigError naming file, line
and key (with "did you mean"); legal but suspicious timing is a warning naming file and key.

Robot file (`robotN_murdoch_params.yaml`): timing of the auction and the lease, utility weights,
sensors, and one skill per task the robot can do (its level, and the evaluator that says whether
the robot can do — and keeps progressing on — the task). Tasks file
(`tasks_murdoch_params.yaml`): each task's id, name, required resources (sensor topics the robot
must have fresh), locations (none, or points where it is done), layers and progress timeout.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import msgspec

from mrta_zenoh import paramdoc
from mrta_zenoh.clock import EPSILON
from mrta_zenoh.limits import COORDINATE, LEVEL, WEIGHT
from mrta_zenoh.paramdoc import Duration, Rate, Id, Text, sized, within
from mrta_zenoh.shared_reads import once
from mrta_zenoh.yamlfile import YamlDoc
from mrta_agent.runtime.params import (Doc, EvaluatorDoc, EvaluatorSpec, SensorParams, Sensors,
                                       TaskDoc, TaskParams, TopicDoc, evaluator_spec,
                                       load_layers_params, pose_topic_of, read_tasks,
                                       require_task, sensor_params)


@dataclass(frozen=True)
class Skill:
    task_id: str
    level: float
    evaluator: EvaluatorSpec


@dataclass(frozen=True)
class MurdochRobot:
    name: str
    spin_rate: float
    control_rate: float
    bid_window: float
    renewal_period: float
    lease_timeout: float
    reannounce_period: float
    give_up_delay: float
    skill_weight: float
    distance_weight: float
    pose_topic: str | None
    sensors: tuple[SensorParams, ...]
    skills: tuple[Skill, ...]

    def skill(self, task_id: str) -> Skill | None:
        return next((s for s in self.skills if s.task_id == task_id), None)


# How long a robot may hold a task without finishing it before the task's auctioneer revokes
# the contract (docs/murdoch.md, "Progress monitoring"): a minute, longer than a point task
# takes to reach and serve; a task that never ends (patrol's) sets it longer than a run.
PROGRESS_TIMEOUT = 60.0


@dataclass(frozen=True)
class MurdochTask:
    id: str
    name: str
    resources: tuple[str, ...]
    locations: tuple[tuple[float, float], ...]
    layers: TaskParams
    progress_timeout: float = PROGRESS_TIMEOUT


@dataclass
class MurdochParams:
    robot: MurdochRobot
    tasks: dict[str, MurdochTask]
    layers: YamlDoc | None = None
    warnings: list[str] = field(default_factory=list)

    def evaluators(self) -> list[EvaluatorSpec]:
        return [s.evaluator for s in self.robot.skills]

    def task_layers(self) -> dict[str, TaskParams]:
        return {t.id: t.layers for t in self.tasks.values()}


class Utility(Doc):
    skill_weight: within(WEIGHT) = 1.0
    distance_weight: within(WEIGHT) = 0.0


class SkillDoc(Doc):
    task_id: Id
    level: within(LEVEL)
    progress: EvaluatorDoc


class RobotFile(Doc):
    """The robot file as written."""

    bid_window: Duration
    renewal_period: Duration
    lease_timeout: Duration
    reannounce_period: Duration
    give_up_delay: Duration
    sensors: Sensors
    skills: sized(SkillDoc, "skill")
    name: Text = ""
    spin_rate: Rate = 10.0
    control_rate: Rate = 10.0
    utility: Utility = msgspec.field(default_factory=Utility)
    pose_topic: Text = ""  # none: the robot's pose is not read


class Location(Doc):
    x: within(COORDINATE)
    y: within(COORDINATE)


class MurdochTaskDoc(TaskDoc):
    """A task of the tasks file: ALLIANCE's keys (id, name, layers), plus the resources it
    needs, the locations where it is done and its progress timeout."""

    resources: sized(TopicDoc, "resource") = []
    locations: sized(Location, "location") = []
    progress_timeout: Duration = PROGRESS_TIMEOUT


def load_robot(path: Path | str) -> tuple[MurdochRobot, list[str]]:
    d = paramdoc.load(path, RobotFile, "a MURDOCH robot parameter file")
    f = d.value
    sensors = sensor_params(d, f.sensors)
    warnings: list[str] = []
    skills: list[Skill] = []
    for i, s in enumerate(f.skills):
        if any(k.task_id == s.task_id for k in skills):
            raise d.error(("skills", i, "task_id"), f"task {s.task_id!r} has two skills")
        skills.append(Skill(s.task_id, s.level, evaluator_spec(
            d, ("skills", i, "progress"), s.task_id, s.progress, sensors)))
    robot = MurdochRobot(
        name=f.name, spin_rate=f.spin_rate, control_rate=f.control_rate,
        bid_window=f.bid_window, renewal_period=f.renewal_period,
        lease_timeout=f.lease_timeout, reannounce_period=f.reannounce_period,
        give_up_delay=f.give_up_delay, skill_weight=f.utility.skill_weight,
        distance_weight=f.utility.distance_weight,
        pose_topic=pose_topic_of(d, f.pose_topic or None, sensors), sensors=sensors,
        skills=tuple(skills))
    tick = 1.0 / robot.spin_rate
    for key in ("bid_window", "renewal_period"):
        if getattr(robot, key) < tick:
            raise d.error((key,), f"{key} {getattr(robot, key):g} s is shorter than the tick "
                          f"period 1/spin_rate = {tick:g} s: it could never be honoured")
    if robot.lease_timeout <= robot.renewal_period:
        raise d.error(("lease_timeout",), f"lease_timeout {robot.lease_timeout:g} s must be "
                      f"longer than renewal_period {robot.renewal_period:g} s, or every lease "
                      "lapses between two renewals")
    if robot.lease_timeout < 2 * robot.renewal_period + tick:
        warnings.append(d.warning(
            ("lease_timeout",), f"lease_timeout {robot.lease_timeout:g} s is less than two "
            f"renewal periods plus a tick ({2 * robot.renewal_period + tick:g} s): one late "
            "renewal makes teammates re-auction a task this robot still does"))
    if robot.reannounce_period <= robot.bid_window:
        raise d.error(("reannounce_period",), f"reannounce_period {robot.reannounce_period:g} s "
                      f"must be longer than bid_window {robot.bid_window:g} s, or a task is "
                      "announced again before its auction closes")
    return robot, warnings


def load_tasks(path: Path | str) -> dict[str, MurdochTask]:
    """The tasks file: ALLIANCE's (id, name, layers), plus resources, locations and the
    progress timeout."""
    return dict(once(path, "murdoch tasks", lambda: {  # once per agent host (shared_reads)
        t.id: MurdochTask(t.id, layers.name, tuple(r.topic_name for r in t.resources),
                          tuple((p.x, p.y) for p in t.locations), layers, t.progress_timeout)
        for *_, t, layers in read_tasks(path, MurdochTaskDoc)}))


def load_params(robot_file, tasks_file, layers_file=None) -> MurdochParams:
    robot, warnings = load_robot(robot_file)
    tasks = load_tasks(tasks_file)
    topics = {s.topic_name for s in robot.sensors}
    for skill in robot.skills:
        require_task(skill.task_id, tasks, robot_file, "skill")
        missing = [r for r in tasks[skill.task_id].resources if r not in topics]
        if missing:
            warnings.append(f"{robot_file}: task {skill.task_id!r} needs {', '.join(missing)}, "
                            "which this robot has no sensor for: it will never bid for it")
    return MurdochParams(robot, tasks, load_layers_params(layers_file), warnings)


def takeover_bound(robot: MurdochRobot, delay: float = 0.0) -> float:
    """The longest a task stays unheld after its holder dies, while an auctioneer survives and
    an idle, capable robot exists, with every delivery delay at most `delay`
    (docs/murdoch.md): the lease lapses (lease_timeout after the last renewal was heard, up to
    `delay` after it was sent), the auctioneer sees it at its next tick and announces, bidders
    answer at their next tick, the window closes and the award goes out at the tick after, and
    the winner claims at its next tick after hearing it (up to `delay` later):
    lease + window + 3 ticks + 2·delay. It holds only while `bids_in_time(robot, delay)`.
    When the dead robot was also the first auctioneer and its token outlives it (frozen, cut
    off), the next one steps in one reannounce_period later."""
    return robot.lease_timeout + robot.bid_window + 3.0 / robot.spin_rate + 2.0 * delay


def bids_in_time(robot: MurdochRobot, delay: float) -> bool:
    """Whether every bid reaches its auctioneer before the window closes: the announcement
    (≤ delay), the bidder's next tick (≤ a tick), the bid (≤ delay), strictly before the tick
    that closes the window. Otherwise an auction may close without the bid, and the task
    waits a reannounce_period for the next one — and so on for as long as delays stay long."""
    return 2.0 * delay + 1.0 / robot.spin_rate < robot.bid_window - EPSILON
