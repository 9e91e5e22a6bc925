"""TeSSI in execution: SSI's coordinator (mrta_agent.ssi.agent: the route adapter, the bid
subjects, the settled rule) driving a `Tessi` logic instead of an `Ssi` one."""

from __future__ import annotations

import logging

from ..ssi.agent import SsiCoordinator
from .auction import Tessi


class TessiCoordinator(SsiCoordinator):
    logic_kinds = Tessi.listens
    logic_class = Tessi
    log = logging.getLogger("mrta.tessi")
    serve_as_awarded = False  # every round's awards all in before a route changes, as before

    def logic_keys(self, keys) -> dict:
        return {"makespan_weight": keys.makespan_weight}
