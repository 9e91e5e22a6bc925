"""`mrta murdoch`: a thin click wrapper over mrta_murdoch.api.run_agent (the options are every
agent's, robot_agent.cli.agent_options)."""

from __future__ import annotations

from pathlib import Path

from mrta_zenoh.bus import BusOptions
from mrta_zenoh.cli.common import user_errors
from robot_agent.cli import agent_options

from .api import run_agent


@agent_options("MURDOCH", "murdoch")
def murdoch(robot_id: str, robot_params: Path, tasks_params: Path, layers_params: Path | None,
            sim_time: bool, seed: int, duration: float | None, crash_at: float | None,
            bus_options: BusOptions) -> None:
    """Run ROBOT_ID's MURDOCH agent: auctions, leases, sensors, evaluators and layers."""
    with user_errors():
        run_agent(robot_id=robot_id, robot_params=robot_params, tasks_params=tasks_params,
                  layers_params=layers_params, bus_options=bus_options, sim_time=sim_time,
                  seed=seed, duration=duration, crash_at=crash_at)
