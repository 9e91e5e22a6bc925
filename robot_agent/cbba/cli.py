"""`mrta cbba`: CBBA's agent verb (the options are every agent's,
mrta_agent.runtime.cli.agent_command)."""

from __future__ import annotations

from ..runtime.cli import agent_command
from .architecture import CBBA

cbba = agent_command(
    CBBA, "Run ROBOT_ID's CBBA agent: build its bundle, reach consensus with its teammates, "
          "serve its bundle's path.")
