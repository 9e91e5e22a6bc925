"""`mrta agent`: ALLIANCE's agent verb (the options are every agent's,
mrta_agent.runtime.cli.agent_command)."""

from __future__ import annotations

from ..runtime.cli import agent_command
from .architecture import ALLIANCE

agent = agent_command(
    ALLIANCE,
    "Run ROBOT_ID's ALLIANCE agent: motivational behaviours, sensors, evaluators and layers.")
