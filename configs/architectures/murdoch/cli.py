"""`mrta murdoch`: a thin click wrapper over mrta_murdoch.api.run_agent (the options are every
agent's, robot_agent.cli.agent_command)."""

from __future__ import annotations

from robot_agent.cli import agent_command

from .api import run_agent

murdoch = agent_command(
    "murdoch", "MURDOCH", "murdoch", run_agent,
    "Run ROBOT_ID's MURDOCH agent: auctions, leases, sensors, evaluators and layers.")
