"""`mrta murdoch`: MURDOCH's agent verb (the options are every agent's,
mrta_agent.runtime.cli.agent_command)."""

from __future__ import annotations

from ..runtime.cli import agent_command
from .architecture import MURDOCH

murdoch = agent_command(
    MURDOCH, "Run ROBOT_ID's MURDOCH agent: auctions, leases, sensors, evaluators and layers.")
