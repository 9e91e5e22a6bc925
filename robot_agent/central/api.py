"""The dispatcher process (`mrta dispatcher`): the problem read from an instance file through the
application's instance kind (mrta_zenoh.instances), the dispatcher's logic (dispatcher.py)
given to the agent runtime's fixed driver, hosted like a robot's agent — the node (a role and a
name of its own, a lockstep participant on simulated time), faults from $MRTA_FAULTS
(`crash:dispatcher@T`: it crashes at a tick, at that simulated time), its process token
declared last — but with no body: no plugins, no layers, no velocity commands.
"""

from __future__ import annotations

import logging
import threading
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

from mrta_zenoh import instances
from mrta_zenoh.bus import Bus, BusOptions
from mrta_zenoh.clock import Clock
from mrta_zenoh.errors import ConfigError
from mrta_zenoh.planning import Problem

from ..runtime.host import AgentOptions, host
from ..runtime.loop import Agent
from ..runtime.plugins import Plugins
from .architecture import CENTRAL, DISPATCHER
from .dispatcher import Dispatcher
from .params import DispatcherParams, load_dispatcher

if TYPE_CHECKING:
    import numpy as np

log = logging.getLogger("mrta.central")


@dataclass(frozen=True)
class DispatcherOptions:
    """What `mrta dispatcher` is asked to do: its parameters, the instance it dispatches (read
    as `application`'s instance kind; None: the file's own `application:` key, or the only
    kind registered), and how it runs."""

    params: Path
    instance: Path
    application: str | None = None
    name: str = DISPATCHER
    bus_options: BusOptions = field(default_factory=BusOptions)
    sim_time: bool = False
    seed: int = 0
    duration: float | None = None
    team: tuple[str, ...] | None = None


def load_problem(path: Path, application: str | None = None) -> tuple[Problem, instances.Loaded]:
    """The instance's planning problem, and the instance (tasks submitted at run time grow
    both: runtime/growth.py)."""
    loaded = instances.load(path, application)
    problem = loaded.kind.problem(loaded.doc)
    if not isinstance(problem, Problem):
        raise ConfigError(f"{path}: its instance kind gave a {type(problem).__name__}, not a "
                          "mrta_zenoh.planning.Problem")
    return problem, loaded


def prepare(options: DispatcherOptions) -> tuple[DispatcherParams, Problem, instances.Loaded]:
    """Read and check both files (ConfigError naming file, line and key) before any bus opens."""
    if options.name != DISPATCHER:
        raise ConfigError(f"--name {options.name!r}: central's robots take queues only from "
                          f"{DISPATCHER!r}")
    return (load_dispatcher(options.params),
            *load_problem(options.instance, options.application))


def dispatcher_agent(name: str, params: DispatcherParams, problem: Problem, bus: Bus,
                     clock: Clock, rng: np.random.Generator | None,
                     instance: instances.Loaded | None = None) -> Agent:
    """The fixed driver given the dispatcher's logic: no plugins, no layers, no body — only
    the instance, which tasks submitted at run time grow (runtime/growth.py)."""
    return Agent(name, CENTRAL, lambda: Dispatcher(problem, params, name), bus, clock, rng,
                 Plugins((), (), {}, None, instance), params.spin_rate, params.spin_rate, log)


def run_dispatcher(options: DispatcherOptions, stop: threading.Event | None = None) -> int:
    params, problem, instance = prepare(options)
    robots = tuple(r.id for r in problem.robots)
    team = (options.team or robots) + (options.name,)
    agent_options = AgentOptions(options.name, options.params, options.instance, None,
                                 options.bus_options, options.sim_time, options.seed,
                                 options.duration, None, team)

    def make(bus, clock, rng) -> Agent:
        return dispatcher_agent(options.name, params, problem, bus, clock, rng, instance)

    return host(make, agent_options, warnings=[], stop=stop, logger=log, role=DISPATCHER,
                describe=f"dispatcher of {len(robots)} robots and {len(problem.tasks)} tasks, "
                         f"objective {params.objective.value}")
