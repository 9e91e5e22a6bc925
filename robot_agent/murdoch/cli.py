"""`mrta murdoch`: a thin click wrapper over mrta_agent.murdoch.api.run_agent (the options are every
agent's, robot_agent.cli.agent_command)."""

from __future__ import annotations

from mrta_agent.runtime.cli import agent_command

from .api import run_agent

murdoch = agent_command(
    "murdoch", "MURDOCH", "murdoch", run_agent,
    "Run ROBOT_ID's MURDOCH agent: auctions, leases, sensors, evaluators and layers.")
