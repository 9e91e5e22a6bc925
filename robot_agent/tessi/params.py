"""TeSSI's parameter files: SSI's (mrta_agent.ssi.params: every key of a robot serving its own
route, and SSI's `resend_period`, `join_wait`, `lookahead`) and TeSSI's own robot key:

* `makespan_weight` (1.0): the weight of the makespan (with the task inserted) in a bid — 1 is
  TeSSI's bid, below 1 TeSSIduo's, the rest of the weight on the travel the task adds
  (docs/tessi.md; the ROPOD implementation of TeSSIduo uses 0.5).
"""

from __future__ import annotations

from functools import partial
from typing import Annotated

import msgspec

from mrta_agent.route import own_route_params as own
from mrta_agent.ssi.params import SsiKeys


class TessiKeys(SsiKeys, kw_only=True):
    makespan_weight: Annotated[float, msgspec.Meta(ge=0.0, le=1.0)] = 1.0


WHAT = "a TeSSI robot parameter file"
KEYS = TessiKeys
load_robot = partial(own.load_robot, what=WHAT, keys=KEYS)
load_params = partial(own.load_params, what=WHAT, keys=KEYS)
