"""central's verbs: `mrta central` (one robot's agent: the options every agent verb takes,
mrta_agent.runtime.cli.agent_command) and `mrta dispatcher` (the dispatcher process, api.py)."""

from __future__ import annotations

from pathlib import Path

import click

from mrta_zenoh.architectures import TEAM_ENV
from mrta_zenoh.bus import BusOptions
from mrta_zenoh.cli.common import SEED_TYPE, bus_options, finite_float
from mrta_zenoh.failure import FAULTS_ENV
from mrta_zenoh.seeds import SEED_ENV

from ..runtime.cli import parse_team, agent_command
from .api import DispatcherOptions, run_dispatcher
from .architecture import CENTRAL, DISPATCHER

central = agent_command(
    CENTRAL, "Run ROBOT_ID's central agent: serve the queue the dispatcher sends, report "
             "progress (sensors, evaluators and layers as every agent).")


@click.command(name="dispatcher", help=(
    "Run central's dispatcher: it re-solves the problem at each arrival, completion or robot "
    "loss and sends each robot its queue (docs/central.md). Its faults come from "
    f"${FAULTS_ENV}, e.g. crash:{DISPATCHER}@T."))
@click.option("--params", "params", required=True, type=click.Path(dir_okay=False, path_type=Path),
              help="The dispatcher's parameters (dispatcher_central_params.yaml): objective, "
                   "progress timeout, solver limits.")
@click.option("--instance", required=True, type=click.Path(dir_okay=False, path_type=Path),
              help="The instance it dispatches: robots, tasks, travel times (an application's "
                   "instance file, e.g. a delivery instance or a run's summary.json).")
@click.option("--application", metavar="APP",
              help="The application whose instance kind reads the file (default: the file's "
                   "own `application:` key, or the only kind registered).")
@click.option("--sim-time", is_flag=True,
              help="Follow the simulator's clock (a lockstep participant) instead of wall time.")
@click.option("--seed", type=SEED_TYPE, default=0, show_default=True, envvar=SEED_ENV,
              help=f"The run's master seed (runners set ${SEED_ENV}): the fault draws of "
                   "what it hears derive from it.")
@click.option("--duration", type=finite_float(min=0, min_open=True),
              help="Stop after this many seconds (of its clock).")
@click.option("--team", metavar="ROBOT,ROBOT,…", envvar=TEAM_ENV, callback=parse_team,
              help="The only robots it dispatches to (launch files set "
                   f"${TEAM_ENV}); default: every robot of the instance.")
@bus_options
def dispatcher(bus_options: BusOptions, params: Path, instance: Path, application: str | None,
               sim_time: bool, seed: int, duration: float | None,
               team: tuple[str, ...] | None) -> None:
    run_dispatcher(DispatcherOptions(params, instance, application, DISPATCHER, bus_options,
                                     sim_time, seed, duration, team))
