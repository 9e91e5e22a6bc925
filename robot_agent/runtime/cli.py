"""`mrta agent`: a thin click wrapper over mrta_agent.alliance.api.run_agent; `agent_command` builds
every architecture's agent command alike."""

from __future__ import annotations

from pathlib import Path
from typing import Callable

import click

from mrta_zenoh.bus import BusOptions
from mrta_zenoh.cli.common import bus_options, finite_float, user_errors



def agent_command(name: str, architecture: str, stem: str, run: Callable[..., int],
                  help: str) -> click.Command:
    """A robot agent command (`mrta agent`, `mrta murdoch`): the options every agent takes —
    its parameter files (named after `stem`), time, seed, duration, fault injection, the bus —
    handed to `run` (the architecture's api.run_agent)."""

    def command(robot_id: str, robot_params: Path, tasks_params: Path,
                layers_params: Path | None, sim_time: bool, seed: int, duration: float | None,
                crash_at: float | None, bus_options: BusOptions) -> None:
        with user_errors():
            run(robot_id=robot_id, robot_params=robot_params, tasks_params=tasks_params,
                layers_params=layers_params, bus_options=bus_options, sim_time=sim_time,
                seed=seed, duration=duration, crash_at=crash_at)

    for option in reversed([
        click.argument("robot_id"),
        click.option("--robot-params", required=True,
                     type=click.Path(dir_okay=False, path_type=Path),
                     help=f"The robot's {architecture} parameters (e.g. "
                          f"robot1_{stem}_params.yaml)."),
        click.option("--tasks-params", required=True,
                     type=click.Path(dir_okay=False, path_type=Path),
                     help=f"The tasks file (tasks_{stem}_params.yaml)."),
        click.option("--layers-params", type=click.Path(dir_okay=False, path_type=Path),
                     help=f"Parameters for the layer plugins (layers_{stem}_params.yaml)."),
        click.option("--sim-time", is_flag=True,
                     help="Follow the simulator's clock instead of wall time."),
        click.option("--seed", type=int, default=0, show_default=True,
                     help="The run's master seed; this robot's stream is derived from it "
                          "and its id."),
        click.option("--duration", type=finite_float(min=0, min_open=True),
                     help="Stop after this many seconds (of the agent's clock)."),
        click.option("--crash-at", type=finite_float(min=0), metavar="SECONDS",
                     help="Fault injection: SIGKILL itself when its clock reaches SECONDS "
                          "(also $MRTA_CRASH=ROBOT@SECONDS,…). Exact in lockstep: "
                          "experiments replay it."),
        bus_options,
    ]):
        command = option(command)
    return click.command(name=name, help=help)(command)

