"""`mrta host SPEC.yaml [bus options]`: run several robots' agents in one process (an agent
host, runtime.agent_host). The spec names the host and gives each robot's arguments exactly as
its architecture's verb takes them — `[ssi, robot1, --robot-params, …, --sim-time]` — so a robot
is configured the same way whether it runs alone (`mrta ssi robot1 …`) or hosted; the bus
options are the host's (its one session), and given per robot they are refused.

    name: host1
    agents:
      - [ssi, robot1, --robot-params, robot1_ssi_params.yaml, --tasks-params, tasks.yaml,
         --sim-time]
      - [ssi, robot2, --robot-params, robot2_ssi_params.yaml, --tasks-params, tasks.yaml,
         --sim-time]
"""

from __future__ import annotations

import logging
from pathlib import Path
from typing import Callable

import click
import msgspec

from mrta_zenoh.architectures import architectures
from mrta_zenoh.bus import BusOptions
from mrta_zenoh.cli.common import bus_options
from mrta_zenoh.errors import ConfigError
from mrta_zenoh.keys import KeyExprError, normalize_robot_id
from mrta_zenoh.shared_reads import shared_reads
from mrta_zenoh.yamlfile import did_you_mean, load_yaml

from .agent_host import Seat, host_agents
from .architecture import AgentArchitecture
from .cli import agent_command
from .host import AgentOptions

BUS_PARAMS = ("connect", "listen", "mode", "zenoh_config", "bus_namespace")


class HostSpec(msgspec.Struct, forbid_unknown_fields=True):
    """A host's spec: its name (its lockstep participant's) and each robot's verb arguments."""

    name: str
    agents: list[list[str]]


def read_spec(path: Path) -> tuple[str, list[Seat]]:
    """The spec's seats (ConfigError naming the file, line and key of what is wrong)."""
    doc = load_yaml(path)
    spec = doc.convert((), HostSpec)
    try:
        normalize_robot_id(spec.name)
    except KeyExprError as exc:
        raise doc.error(("name",), str(exc)) from None
    for i, argv in enumerate(spec.agents):
        if len(argv) < 2:
            raise doc.error(("agents", i), "expected [ARCHITECTURE_VERB, ROBOT_ID, options…]")
    archs = agent_architectures()  # looked up once, not once per robot
    with shared_reads():  # the files the robots share, read once for all of them
        return spec.name, [seat_of(argv, lambda why, i=i: doc.error(("agents", i), why), archs)
                           for i, argv in enumerate(spec.agents)]


def agent_architectures() -> dict[str, AgentArchitecture]:
    """The registered architectures whose robots run on this runtime, by their verb."""
    return {a.command: a for a in architectures().values() if isinstance(a, AgentArchitecture)}


def seat_of(argv: list[str], error: Callable[[str], ConfigError],
            archs: dict[str, AgentArchitecture] | None = None) -> Seat:
    """One robot's seat from its verb's arguments (`[verb, robot_id, …]`), parsed by the very
    command `mrta <verb>` is (agent_command), so every option means what it means there."""
    verb, args = argv[0], argv[1:]
    archs = agent_architectures() if archs is None else archs
    arch = archs.get(verb)
    if arch is None:
        raise error(f"{verb!r} is no architecture's agent verb" + did_you_mean(verb, archs))
    command = agent_command(arch, "")
    try:
        with command.make_context(f"mrta {verb}", list(args)) as ctx:
            params = dict(ctx.params)
    except click.UsageError as exc:
        raise error(f"{' '.join(argv[:2])}: {exc.format_message()}") from None
    given = [p for p in BUS_PARAMS if params.get(p) not in (None, (), "", "peer")]
    if given:
        raise error(f"{' '.join(argv[:2])}: bus options belong to the host's command line, "
                    f"not a robot's ({', '.join(given)})")
    for p in BUS_PARAMS:
        params.pop(p, None)
    options = AgentOptions(**params)
    prepared = arch.prepare(options)
    return Seat(options, lambda bus, clock, rng: arch.agent(prepared, bus, clock, rng),
                prepared.describe, tuple(prepared.warnings), logging.getLogger(arch.logger_name))


@click.command(name="host")
@click.argument("spec", type=click.Path(exists=True, dir_okay=False, path_type=Path))
@bus_options
def host(spec: Path, bus_options: BusOptions) -> None:
    """Run the agents of the robots SPEC lists in this one process (an agent host): each robot
    keeps its keys, tokens, parameters, seed stream and faults; one Zenoh session and one
    lockstep participant serve them all. Each robot's arguments are its architecture's verb's
    (`mrta ssi ROBOT_ID …`); the bus options are the host's."""
    name, seats = read_spec(spec)
    host_agents(seats, bus_options, name=normalize_robot_id(name))
