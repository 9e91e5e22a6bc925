"""`mrta tessi`: TeSSI's agent verb (the options are every agent's,
mrta_agent.runtime.cli.agent_command)."""

from __future__ import annotations

from ..runtime.cli import agent_command
from .architecture import TESSI

tessi = agent_command(
    TESSI, "Run ROBOT_ID's TeSSI agent: bid the makespan of its temporal network with a task "
           "inserted in sequential single-item auctions, serve the resulting schedule.")
