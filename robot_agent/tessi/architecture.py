"""TeSSI (docs/tessi.md) as tools and the agent runtime see it: the object registered under
`mrta.architectures` as `tessi` — SSI's contract (mrta_agent.ssi.architecture) on its own
namespace, with TeSSI's logic and parameter keys."""

from __future__ import annotations

from ..ssi.architecture import SsiArchitecture
from . import params as tessi_params
from .agent import TessiCoordinator


class TessiArchitecture(SsiArchitecture):
    name = "tessi"
    title = "TeSSI"
    namespace = "tessi"
    executable = "tessi/agent"
    command = "tessi"
    param_stem = "tessi"
    objective = "makespan"
    logger_name = "mrta.tessi"
    params = tessi_params
    coordinator_class = TessiCoordinator
    bound_formula = ("none: re-opened within a tick of the loss, then served in the winner's "
                     "schedule order")


TESSI = TessiArchitecture()
