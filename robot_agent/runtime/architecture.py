"""The agent side of the architecture contract: how an architecture's robot agent is prepared
from its parameter files, which decision logic the fixed driver (`loop.Agent`) is given, and its
`mrta` verb. An architecture registered under `mrta.architectures` is an instance of a subclass.

To add an architecture (docs/architecture.md, "Adding an architecture"): subclass
AgentArchitecture, set the class attributes of `mrta_zenoh.architectures.Architecture`,
implement `prepare`, `coordinator`, `doing` and `takeover_bound` (and `process_agent` if it
names `processes`, such as a dispatcher), register the instance under
`mrta.architectures` and its verb under `mrta.commands` / `mrta.executables`.
"""

from __future__ import annotations

import logging
import threading
from abc import abstractmethod
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

from mrta_zenoh.architectures import Architecture
from mrta_zenoh.bus import Bus
from mrta_zenoh.clock import Clock

from .host import AgentOptions, host
from .coordinator import Coordinator
from .loop import Agent
from .plugins import Plugins

if TYPE_CHECKING:
    import numpy as np  # annotations only: numpy loads when a plugin draws (mrta_zenoh.seeds)


@dataclass
class Prepared:
    """Everything read from a robot's parameter files before any bus opens (a bad file is bad
    input, exit 2, and nothing runs): the architecture's parameters, the robot's plugins, the
    two loop rates and the warnings to log."""

    robot_id: str
    params: Any
    plugins: Plugins
    spin_rate: float
    control_rate: float
    describe: str
    warnings: list[str] = field(default_factory=list)


class AgentArchitecture(Architecture):
    """An architecture whose robots run on mrta_agent's runtime."""

    logger_name: str = "mrta.agent"

    @abstractmethod
    def prepare(self, options: AgentOptions) -> Prepared:
        """Read and check the robot's parameter files (ConfigError naming file, line, key)."""

    def check_files(self, robot_id: str, robot_params: Path, tasks_params: Path,
                    layers_params: Path | None = None) -> None:
        """The contract's file check: exactly what the agent's start reads (prepare)."""
        self.prepare(AgentOptions(robot_id, robot_params, tasks_params, layers_params))

    def layer_sections(self, robot_id: str, robot_params: Path,
                       tasks_params: Path) -> frozenset[str]:
        """The sections the robot's plugins declare (Plugin.sections, Layer.params_section)."""
        prepared = self.prepare(AgentOptions(robot_id, robot_params, tasks_params, None))
        return frozenset(name for name, _ in prepared.plugins.sections)

    @abstractmethod
    def coordinator(self, prepared: Prepared) -> Coordinator:
        """The decision logic for one robot, fresh (called again when time restarts)."""

    def agent(self, prepared: Prepared, bus: Bus, clock: Clock,
              rng: np.random.Generator | None = None) -> Agent:
        """The fixed driver, given this architecture's logic."""
        return Agent(prepared.robot_id, self, lambda: self.coordinator(prepared), bus,
                     clock, rng, prepared.plugins, prepared.spin_rate, prepared.control_rate,
                     logging.getLogger(self.logger_name))

    def process_agent(self, name: str, config: Path, bus: Bus, clock: Clock,
                      rng: np.random.Generator | None = None) -> Agent:
        """The fixed driver for process `name` (one of `processes`: central's dispatcher), built
        from an application package's config folder as its launch file builds it, so that the
        process runs in-process beside the robots' agents (the conformance suite,
        tests/test_conformance.py, crashes a robot with it there). An architecture with
        processes overrides this; there is no default way to build one."""
        raise NotImplementedError(
            f"{self.name} names processes {list(self.processes)} but not how to build "
            f"{name!r} in-process (AgentArchitecture.process_agent)")

    def run(self, options: AgentOptions, stop: threading.Event | None = None) -> int:
        """What the architecture's `mrta` verb does: prepare, then host the agent until stopped."""
        prepared = self.prepare(options)
        return host(lambda bus, clock, rng: self.agent(prepared, bus, clock, rng), options,
                    warnings=prepared.warnings, describe=prepared.describe, stop=stop,
                    logger=logging.getLogger(self.logger_name))
