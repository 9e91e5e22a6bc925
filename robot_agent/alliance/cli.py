"""`mrta agent`: a thin click wrapper over mrta_agent.alliance.api.run_agent (the options are
every agent's, mrta_agent.runtime.cli.agent_command)."""

from __future__ import annotations

from ..runtime.cli import agent_command
from .api import run_agent


agent = agent_command(
    "agent", "ALLIANCE", "alliance", run_agent,
    "Run ROBOT_ID's ALLIANCE agent: motivational behaviours, sensors, evaluators and layers.")
