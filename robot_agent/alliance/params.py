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

from mrta_zenoh import paramdoc
from mrta_zenoh.limits import IMPATIENCE, THRESHOLD
from mrta_zenoh.paramdoc import Duration, Id, Rate, Text, sized, within
from mrta_zenoh.yamlfile import YamlDoc

from ..runtime.params import (Doc, EvaluatorDoc, SensorParams, Sensors, TaskParams, load_layers_params,
                              load_tasks_params, require_task, sensor_params, sensor_topics)


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


class Acquiescence(Doc):
    yielding_delay: Duration
    giving_up_delay: Duration


class Impatience(Doc):
    fast_rate: within(IMPATIENCE, positive=True)


class Motivation(Doc):
    threshold: within(THRESHOLD, positive=True)
    acquiescence: Acquiescence
    impatience: Impatience
    sensory_feedback: EvaluatorDoc


class BehaviourSetDoc(Doc):
    task_id: Id
    task_expected_duration: Duration
    motivational_behaviour: Motivation


class RobotFile(Doc):
    """The robot file as written (the dissertation's layout)."""

    spin_rate: Rate
    broadcast_rate: Rate
    timeout_duration: Duration
    sensors: Sensors
    behaviour_sets: sized(BehaviourSetDoc, "behaviour_set")
    name: Text = ""
    id: str | None = None  # the reference files' own label of the robot; the command line's wins
    buffer_horizon: Duration = 10.0
    control_rate: Rate = 10.0
    max_expected_duration: Duration = 3600.0


def load_robot_params(path: Path | str) -> tuple[RobotParams, list[str]]:
    d = paramdoc.load(path, RobotFile, "a robot parameter file")
    f = d.value
    sensors = sensor_params(d, f.sensors)
    warnings: list[str] = []
    sets = []
    seen_tasks: set[str] = set()
    for i, b in enumerate(f.behaviour_sets):
        bpath = ("behaviour_sets", i)
        mpath = bpath + ("motivational_behaviour",)
        m = b.motivational_behaviour
        ftopics = sensor_topics(d, mpath + ("sensory_feedback", "sensors"),
                                m.sensory_feedback.sensors, sensors)
        if b.task_id in seen_tasks:
            raise d.error(bpath + ("task_id",), f"task {b.task_id!r} has two behaviour sets")
        seen_tasks.add(b.task_id)
        bs = BehaviourSetParams(
            task_id=b.task_id, expected_duration=b.task_expected_duration,
            threshold=m.threshold, yielding_delay=m.acquiescence.yielding_delay,
            giving_up_delay=m.acquiescence.giving_up_delay, fast_rate=m.impatience.fast_rate,
            evaluator_plugin=m.sensory_feedback.plugin_name, evaluator_topics=ftopics,
            where=d.where(mpath + ("sensory_feedback", "plugin_name")))
        if bs.yielding_delay > bs.giving_up_delay:
            warnings.append(d.warning(
                mpath + ("acquiescence", "yielding_delay"),
                f"yielding_delay {bs.yielding_delay:g} s is longer than giving_up_delay "
                f"{bs.giving_up_delay:g} s: this robot gives up before it would ever yield"))
        sets.append(bs)
    robot = RobotParams(
        name=f.name, spin_rate=f.spin_rate, broadcast_rate=f.broadcast_rate,
        timeout_duration=f.timeout_duration, buffer_horizon=f.buffer_horizon,
        sensors=sensors, behaviour_sets=tuple(sets), control_rate=f.control_rate,
        max_expected_duration=f.max_expected_duration)
    tick = 1.0 / robot.spin_rate
    if robot.timeout_duration <= tick:
        raise d.error(("timeout_duration",), f"timeout_duration {robot.timeout_duration:g} s must "
                      f"be longer than the tick period 1/spin_rate = {tick:g} s, or a teammate "
                      "heard between two ticks is never seen")
    period = effective_broadcast_period(robot)
    if robot.timeout_duration < 2 * period:
        warnings.append(d.warning(
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
