"""ALLIANCE parameters in the dissertation's YAML layout (the reference files load unchanged).

Strict: a missing mandatory key, a non-positive rate or τ, a value outside its sane range
(mrta_zenoh.limits: durations a millisecond to a day, rates 0.01–1000 Hz, θ and δ_fast in
motivation units), or an unknown key in the robot or tasks file is a ConfigError naming file,
line, key and range (with "did you mean"). The layers file belongs to
the layer plugins, so it is only required to be a mapping. Legal but suspicious values are
returned as warnings naming file and key.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

from mrta_zenoh.limits import IMPATIENCE, THRESHOLD
from mrta_zenoh.yamlfile import YamlDoc, sized_array

from ..runtime.params import (SensorParams, StrictMapping, TaskParams, load_layers_params,
                              load_sensor_topics, load_tasks_params, open_robot_file,
                              require_task, task_id_of)


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


@dataclass
class AgentParams:
    robot: RobotParams
    tasks: dict[str, TaskParams]
    layers: YamlDoc | None = None  # the layers file; plugins' typed sections are read from it
    warnings: list[str] = field(default_factory=list)


ROBOT_KEYS = {"name", "spin_rate", "broadcast_rate", "timeout_duration", "buffer_horizon",
              "sensors", "behaviour_sets", "control_rate", "id", "max_expected_duration"}


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
            expected_duration=b.duration("task_expected_duration"),
            threshold=m.get("threshold", float, positive=True, within=THRESHOLD),
            yielding_delay=a.duration("yielding_delay"),
            giving_up_delay=a.duration("giving_up_delay"),
            fast_rate=i.get("fast_rate", float, positive=True, within=IMPATIENCE),
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
        timeout_duration=top.duration("timeout_duration"),
        buffer_horizon=top.duration("buffer_horizon", 10.0),
        sensors=sensors, behaviour_sets=tuple(sets),
        control_rate=top.rate("control_rate", 10.0),
        max_expected_duration=top.duration("max_expected_duration", 3600.0),
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


def load_agent_params(robot_file, tasks_file, layers_file=None) -> AgentParams:
    robot, warnings = load_robot_params(robot_file)
    tasks = load_tasks_params(tasks_file)
    for bs in robot.behaviour_sets:
        require_task(bs.task_id, tasks, robot_file, "behaviour set")
    return AgentParams(robot, tasks, load_layers_params(layers_file), warnings)
