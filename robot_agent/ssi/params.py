"""SSI's parameter files (mrta_agent.route.own_route_params: the keys every robot serving its
own route has) and SSI's own robot keys, each with its default:

* `resend_period` (s, 0.5): how often the auctioneer repeats a Round still missing bids, and a
  bidder the report of tasks it served (docs/ssi.md, "On the bus");
* `join_wait` (s, 1.0): how long the first auctioneer waits for robots of the instance it has
  not heard of yet;
* `lookahead` (s, 0): a task is auctioned from this long before its arrival.
"""

from __future__ import annotations

from mrta_agent.route import own_route_params as own
from mrta_agent.route.own_route_params import OwnRouteParams, OwnRouteRobot
from mrta_agent.runtime.params import Doc
from mrta_zenoh.paramdoc import Duration, NonNegative

RESEND_PERIOD = 0.5
JOIN_WAIT = 1.0


class SsiKeys(Doc, kw_only=True):
    resend_period: Duration = RESEND_PERIOD
    join_wait: Duration = JOIN_WAIT
    lookahead: NonNegative = 0.0


WHAT = "an SSI robot parameter file"
KEYS = SsiKeys


def load_robot(path) -> OwnRouteRobot:
    return own.load_robot(path, WHAT, KEYS)


def load_params(robot_id: str, robot_file, tasks_file, layers_file=None) -> OwnRouteParams:
    return own.load_params(robot_id, robot_file, tasks_file, layers_file, WHAT, KEYS)
