"""The options every architecture's agent verb takes (`mrta agent`, `mrta murdoch`, a third
party's), spelled out once: `agent_command(arch)` builds the verb, a thin wrapper that makes an
`AgentOptions` and hands it to the architecture's `run`."""

from __future__ import annotations

from pathlib import Path

import click

from mrta_zenoh.architectures import TEAM_ENV
from mrta_zenoh.bus import BusOptions
from mrta_zenoh.cli.common import SEED_TYPE, bus_options, finite_float
from mrta_zenoh.failure import FAULTS_ENV
from mrta_zenoh.keys import KeyExprError, normalize_robot_id
from mrta_zenoh.seeds import SEED_ENV

from .architecture import AgentArchitecture
from .host import AgentOptions


def parse_team(ctx: click.Context, param: click.Parameter, value: str | None) -> tuple[str, ...] | None:
    """`robot1,robot2,…` → ids; empty or absent → None (the open team). A bad id is a usage
    error naming the option."""
    if value is None or not value.strip():
        return None
    try:
        return tuple(normalize_robot_id(r) for r in value.split(",") if r.strip())
    except KeyExprError as exc:
        raise click.BadParameter(str(exc), ctx=ctx, param=param) from None


def agent_command(arch: AgentArchitecture, help: str) -> click.Command:
    """`mrta <arch.command> ROBOT_ID --robot-params … --tasks-params … [--layers-params …]
    [--sim-time] [--seed] [--duration] [--crash-at] [--team] [bus options]`."""
    stem = arch.param_stem

    def command(bus_options: BusOptions, **kwargs) -> None:
        arch.run(AgentOptions(bus_options=bus_options, **kwargs))

    for option in reversed([
        click.argument("robot_id"),
        click.option("--robot-params", required=True,
                     type=click.Path(dir_okay=False, path_type=Path),
                     help=f"The robot's {arch.title} parameters (e.g. robot1_{stem}_params.yaml)."),
        click.option("--tasks-params", required=True,
                     type=click.Path(dir_okay=False, path_type=Path),
                     help=f"The tasks file (tasks_{stem}_params.yaml)."),
        click.option("--layers-params", type=click.Path(dir_okay=False, path_type=Path),
                     help=f"Parameters for the layer plugins (layers_{stem}_params.yaml)."),
        click.option("--sim-time", is_flag=True,
                     help="Follow the simulator's clock instead of wall time."),
        click.option("--seed", type=SEED_TYPE, default=0, show_default=True, envvar=SEED_ENV,
                     help="The run's master seed, 0 to 2^63 − 1; this robot's stream is "
                          f"derived from it and its id. Runners set ${SEED_ENV} for every "
                          "process of a run."),
        click.option("--duration", type=finite_float(min=0, min_open=True),
                     help="Stop after this many seconds (of the agent's clock)."),
        click.option("--team", metavar="ROBOT,ROBOT,…", envvar=TEAM_ENV, callback=parse_team,
                     help="The only robots counted as teammates (the application's robots; "
                          f"launch files set ${TEAM_ENV}). Others holding an agent token are "
                          "ignored and counted. Not given or empty: anyone holding one."),
        click.option("--crash-at", type=finite_float(min=0), metavar="SECONDS",
                     help="Fault injection: SIGKILL itself when its clock reaches SECONDS; "
                          f"shorthand for crash:ROBOT_ID@SECONDS in ${FAULTS_ENV}, which "
                          "carries every fault of a run (crash, stall, partition, loss, "
                          "latency: docs/delivery.md, Fault grammar). Exact in lockstep: "
                          "experiments replay it."),
        bus_options,
    ]):
        command = option(command)
    return click.command(name=arch.command, help=help)(command)
