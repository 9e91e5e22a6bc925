"""`mrta agent`: run one robot's ALLIANCE agent (high and low level) in this process."""

from __future__ import annotations

import logging
import threading
from pathlib import Path

import click
import numpy as np

from mrta_zenoh import keys
from mrta_zenoh.bus import BusOptions, open_bus
from mrta_zenoh.cli.common import bus_options, user_errors
from mrta_zenoh.clock import SimClock, WallClock
from mrta_zenoh.lifecycle import stop_on_signals
from mrta_zenoh.messages import Clock as ClockMsg

from .agent import Agent
from .params import load_agent_params

log = logging.getLogger("mrta.agent")


def main(robot_id: str, robot_params: Path, tasks_params: Path, layers_params: Path | None,
         bus_opts: BusOptions, sim_time: bool = False, seed: int = 0,
         stop: threading.Event | None = None, duration: float | None = None) -> int:
    with user_errors():
        rid = keys.normalize_robot_id(robot_id)
        params = load_agent_params(robot_params, tasks_params, layers_params)
    for w in params.warnings:
        click.echo(f"warning: {w}", err=True)
    clock = SimClock() if sim_time else WallClock()
    with user_errors(), stop_on_signals(stop) as stop, open_bus(bus_opts) as bus:
        # Plugins are built inside Agent(); a bad plugin name is bad input (exit 2).
        agent = Agent(rid, params, bus, clock, np.random.default_rng(seed), str(robot_params))
        if sim_time:
            bus.subscribe(keys.CLOCK, lambda s: clock.on_clock(s.message.stamp), msg_type=ClockMsg)
        agent.start()
        agent.declare_alive()
        log.info("%s: ready (%d behaviour sets, %s time)", rid, len(params.robot.behaviour_sets),
                 "simulation" if sim_time else "wall")
        try:
            if sim_time:
                while not stop.is_set() and not clock.started.wait(0.1):
                    pass
            until = None if duration is None else clock.now() + duration
            agent.run(stop, until)
        finally:
            agent.shutdown()
    return 0


@click.command()
@click.argument("robot_id")
@click.option("--robot-params", required=True, type=click.Path(dir_okay=False, path_type=Path),
              help="The robot's ALLIANCE parameters (e.g. robot1_alliance_params.yaml).")
@click.option("--tasks-params", required=True, type=click.Path(dir_okay=False, path_type=Path),
              help="The tasks file (tasks_alliance_params.yaml).")
@click.option("--layers-params", type=click.Path(dir_okay=False, path_type=Path),
              help="Parameters for the layer plugins (layers_alliance_params.yaml).")
@click.option("--sim-time", is_flag=True, help="Follow the simulator's clock instead of wall time.")
@click.option("--seed", type=int, default=0, show_default=True, help="Seed for the plugins' RNG.")
@click.option("--duration", type=float, help="Stop after this many seconds (of the agent's clock).")
@bus_options
def agent(robot_id: str, robot_params: Path, tasks_params: Path, layers_params: Path | None,
          sim_time: bool, seed: int, duration: float | None, bus_options: BusOptions) -> None:
    """Run ROBOT_ID's ALLIANCE agent: motivational behaviours, sensors, evaluators and layers."""
    logging.getLogger("mrta.agent").setLevel(logging.INFO)
    if not logging.getLogger().handlers:
        logging.basicConfig(format="%(levelname)s %(name)s: %(message)s")
    main(robot_id, robot_params, tasks_params, layers_params, bus_options, sim_time, seed,
         duration=duration)
