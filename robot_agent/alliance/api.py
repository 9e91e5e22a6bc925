"""Run one robot's ALLIANCE agent: what `mrta agent` does, callable from Python and tests.

Also what other tools may ask of ALLIANCE without knowing its internals: the takeover bound a
run is measured against (the patrol demo and `mrta experiment` use it).
"""

from __future__ import annotations

import math
import threading
from pathlib import Path

from mrta_zenoh.bus import BusOptions
from mrta_zenoh.errors import ConfigError
from mrta_zenoh.keys import normalize_robot_id

from .agent import Agent, Plugins
from .params import AgentParams, load_agent_params, load_robot_params
from ..runtime.host import host


def prepare(*, robot_id: str, robot_params: Path, tasks_params: Path,
            layers_params: Path | None = None) -> tuple[str, AgentParams, Plugins]:
    """Everything that can fail on bad input, before any bus is opened (ConfigError → exit 2)."""
    rid = normalize_robot_id(robot_id)
    params = load_agent_params(robot_params, tasks_params, layers_params)
    plugins = Plugins.for_alliance(params)
    params.warnings += plugins.unread_warnings()
    return rid, params, plugins


def run_agent(*, robot_id: str, robot_params: Path, tasks_params: Path,
              layers_params: Path | None = None, bus_options: BusOptions,
              sim_time: bool = False, seed: int = 0, duration: float | None = None,
              crash_at: float | None = None, stop: threading.Event | None = None) -> int:
    rid, params, plugins = prepare(robot_id=robot_id, robot_params=robot_params,
                                   tasks_params=tasks_params, layers_params=layers_params)
    return host(lambda bus, clock, rng: Agent(rid, params, bus, clock, rng, plugins),
                robot_id=rid, warnings=params.warnings, seed=seed, bus_options=bus_options,
                sim_time=sim_time, duration=duration, crash_at=crash_at, stop=stop,
                describe=f"{len(params.robot.behaviour_sets)} behaviour sets")


def takeover_bound(robot_params: Path, task: str) -> float:
    """τ + ⌈θ / fast_rate⌉ / ρ + one tick: the longest a robot with these parameters takes to
    pick up `task` after the robot doing it dies (its last broadcast lapses after τ, then
    impatience grows at fast_rate per tick from 0 to θ)."""
    robot, _ = load_robot_params(robot_params)
    for bs in robot.behaviour_sets:
        if bs.task_id == task:
            ticks = math.ceil(bs.threshold / bs.fast_rate)
            return robot.timeout_duration + (ticks + 1) / robot.spin_rate
    raise ConfigError(f"no behaviour set for task {task!r}", file=str(robot_params))
