"""Run one robot's MURDOCH agent: what `mrta murdoch` does, callable from Python and tests;
and the takeover bound a run is measured against."""

from __future__ import annotations

import logging
import threading
from pathlib import Path

from mrta_zenoh.bus import BusOptions
from mrta_zenoh.keys import normalize_robot_id
from mrta_agent.runtime.host import host

from . import params as murdoch_params
from .agent import MurdochAgent, plugins_for
from .params import MurdochParams

log = logging.getLogger("mrta.murdoch")


def prepare(*, robot_id: str, robot_params: Path, tasks_params: Path,
            layers_params: Path | None = None):
    """Everything that can fail on bad input, before any bus is opened (ConfigError → exit 2)."""
    rid = normalize_robot_id(robot_id)
    params: MurdochParams = murdoch_params.load_params(robot_params, tasks_params, layers_params)
    plugins = plugins_for(params)
    params.warnings += plugins.unread_warnings()
    return rid, params, plugins


def run_agent(*, robot_id: str, robot_params: Path, tasks_params: Path,
              layers_params: Path | None = None, bus_options: BusOptions,
              sim_time: bool = False, seed: int = 0, duration: float | None = None,
              crash_at: float | None = None, stop: threading.Event | None = None) -> int:
    rid, params, plugins = prepare(robot_id=robot_id, robot_params=robot_params,
                                   tasks_params=tasks_params, layers_params=layers_params)
    return host(lambda bus, clock, rng: MurdochAgent(rid, params, bus, clock, rng, plugins),
                robot_id=rid, warnings=params.warnings, seed=seed, bus_options=bus_options,
                sim_time=sim_time, duration=duration, crash_at=crash_at, stop=stop,
                describe=f"MURDOCH, {len(params.robot.skills)} skills", logger=log)


def takeover_bound(robot_params: Path, task: str) -> float:
    """lease + bid window + 3 ticks (params.takeover_bound); `task` is accepted for the same
    signature as ALLIANCE's bound, which differs per task."""
    robot, _ = murdoch_params.load_robot(robot_params)
    return murdoch_params.takeover_bound(robot)
