"""`mrta ssi`: SSI's agent verb (the options are every agent's,
mrta_agent.runtime.cli.agent_command)."""

from __future__ import annotations

from ..runtime.cli import agent_command
from .architecture import SSI

ssi = agent_command(
    SSI, "Run ROBOT_ID's SSI agent: bid in sequential single-item auctions (clear them as the "
         "lowest-id live robot), serve the path its awards built.")
