"""SSI's parameter files (mrta_agent.route.own_route_params: the keys every robot serving its
own route has) and SSI's own robot keys, each with its default:

* `resend_period` (s, 0.5): how often the auctioneer repeats a Round still missing bids, and a
  bidder the report of tasks it served (docs/ssi.md, "On the bus");
* `join_wait` (s, 1.0): how long the first auctioneer waits for robots of the instance it has
  not heard of yet;
* `lookahead` (s, 0): a task is auctioned from this long before its arrival.
"""

from __future__ import annotations

from dataclasses import dataclass

from mrta_agent.route import own_route_params as own
from mrta_agent.route.own_route_params import OwnRouteParams, OwnRouteRobot, lookahead
from mrta_agent.runtime.params import StrictMapping

RESEND_PERIOD = 0.5
JOIN_WAIT = 1.0


@dataclass(frozen=True)
class SsiKeys:
    resend_period: float = RESEND_PERIOD
    join_wait: float = JOIN_WAIT
    lookahead: float = 0.0


def read_keys(top: StrictMapping) -> SsiKeys:
    return SsiKeys(top.duration("resend_period", RESEND_PERIOD),
                   top.duration("join_wait", JOIN_WAIT), lookahead(top))


WHAT = "an SSI robot parameter file"
KEYS = set(SsiKeys.__dataclass_fields__)


def load_robot(path) -> OwnRouteRobot:
    return own.load_robot(path, WHAT, KEYS, read_keys)


def load_params(robot_id: str, robot_file, tasks_file, layers_file=None) -> OwnRouteParams:
    return own.load_params(robot_id, robot_file, tasks_file, layers_file, WHAT, KEYS, read_keys)
