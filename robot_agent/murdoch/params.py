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

from mrta_zenoh.clock import EPSILON
from mrta_zenoh.limits import COORDINATE, LEVEL, WEIGHT
from mrta_zenoh.yamlfile import YamlDoc, did_you_mean, sized_array
from mrta_agent.runtime.params import SensorParams, StrictMapping, TaskParams, iter_tasks, load_layers_params, load_sensor_topics, open_robot_file, require_task, task_id_of
from mrta_agent.runtime.plugins import EvaluatorSpec


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


ROBOT_KEYS = {"name", "spin_rate", "control_rate", "bid_window", "renewal_period",
              "lease_timeout", "reannounce_period", "give_up_delay", "utility", "pose_topic",
              "sensors", "skills"}


def load_robot(path: Path | str) -> tuple[MurdochRobot, list[str]]:
    doc, top, sensors = open_robot_file(path, ROBOT_KEYS, "a MURDOCH robot parameter file")
    warnings: list[str] = []
    topics = {s.topic_name for s in sensors}
    u = StrictMapping(doc, ("utility",), {"skill_weight", "distance_weight"}) \
        if "utility" in top.data else None
    skills: list[Skill] = []
    for spath, _ in sized_array(doc, ("skills",), "skill"):
        s = StrictMapping(doc, spath, {"task_id", "level", "progress"})
        task_id = task_id_of(s, "task_id")
        if any(k.task_id == task_id for k in skills):
            raise doc.error(spath + ("task_id",), f"task {task_id!r} has two skills")
        p = StrictMapping(doc, spath + ("progress",), {"plugin_name", "sensors"})
        ptopics = load_sensor_topics(doc, spath + ("progress", "sensors"), topics)
        level = s.get("level", float, within=LEVEL)
        skills.append(Skill(task_id, level, EvaluatorSpec(
            task_id, p.get("plugin_name", str), ptopics, p.where("plugin_name"))))
    pose_topic = top.get("pose_topic", str, None)
    if pose_topic is not None and pose_topic not in topics:
        raise doc.error(("pose_topic",), f"pose_topic {pose_topic!r} is not among the robot's "
                        f"sensors ({', '.join(sorted(topics)) or 'none'})" + did_you_mean(pose_topic, topics))
    robot = MurdochRobot(
        name=top.get("name", str, ""),
        spin_rate=top.rate("spin_rate", 10.0),
        control_rate=top.rate("control_rate", 10.0),
        bid_window=top.duration("bid_window"),
        renewal_period=top.duration("renewal_period"),
        lease_timeout=top.duration("lease_timeout"),
        reannounce_period=top.duration("reannounce_period"),
        give_up_delay=top.duration("give_up_delay"),
        skill_weight=u.get("skill_weight", float, 1.0, within=WEIGHT) if u else 1.0,
        distance_weight=u.get("distance_weight", float, 0.0, within=WEIGHT) if u else 0.0,
        pose_topic=pose_topic, sensors=sensors, skills=tuple(skills))
    tick = 1.0 / robot.spin_rate
    for key in ("bid_window", "renewal_period"):
        if getattr(robot, key) < tick:
            raise doc.error((key,), f"{key} {getattr(robot, key):g} s is shorter than the tick "
                            f"period 1/spin_rate = {tick:g} s: it could never be honoured")
    if robot.lease_timeout <= robot.renewal_period:
        raise doc.error(("lease_timeout",), f"lease_timeout {robot.lease_timeout:g} s must be "
                        f"longer than renewal_period {robot.renewal_period:g} s, or every lease "
                        "lapses between two renewals")
    if robot.lease_timeout < 2 * robot.renewal_period + tick:
        warnings.append(doc.warning(
            ("lease_timeout",), f"lease_timeout {robot.lease_timeout:g} s is less than two "
            f"renewal periods plus a tick ({2 * robot.renewal_period + tick:g} s): one late "
            "renewal makes teammates re-auction a task this robot still does"))
    if robot.reannounce_period <= robot.bid_window:
        raise doc.error(("reannounce_period",), f"reannounce_period {robot.reannounce_period:g} s "
                        f"must be longer than bid_window {robot.bid_window:g} s, or a task is "
                        "announced again before its auction closes")
    return robot, warnings


def load_tasks(path: Path | str) -> dict[str, MurdochTask]:
    """The tasks file: ALLIANCE's (id, name, layers), plus resources, locations and the
    progress timeout."""
    tasks: dict[str, MurdochTask] = {}
    for r, layers in iter_tasks(path, frozenset({"resources", "locations", "progress_timeout"})):
        doc, tpath = r.doc, r.path
        resources = []
        if "resources" in r.data:
            for rp, _ in sized_array(doc, tpath + ("resources",), "resource"):
                resources.append(StrictMapping(doc, rp, {"topic_name"}).get("topic_name", str))
        locations = []
        if "locations" in r.data:
            for lp, _ in sized_array(doc, tpath + ("locations",), "location"):
                m = StrictMapping(doc, lp, {"x", "y"})
                locations.append((m.get("x", float, within=COORDINATE),
                                  m.get("y", float, within=COORDINATE)))
        tasks[layers.id] = MurdochTask(layers.id, layers.name, tuple(resources),
                                       tuple(locations), layers,
                                       r.duration("progress_timeout", PROGRESS_TIMEOUT))
    return tasks


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
