"""CBBA's parameter files (mrta_agent.route.own_route_params: the keys every robot serving its
own route has) and CBBA's own robot keys, each with its default:

* `discount` (λ per second, 0.95) and `bundle_limit` (L_t, none): the score (docs/cbba.md);
* `resend_period` (s, 1.0): the state is sent at every change and at least this often;
* `settle` (s, 1.0): how long the robot's winning-bid table must stay unchanged before its route
  is served (docs/cbba.md, "In execution");
* `comm_range` (m, none): messages from robots farther away are not heard;
* `lookahead` (s, 0): a task is bid on from this long before its arrival.
"""

from __future__ import annotations

from mrta_agent.route import own_route_params as own
from mrta_agent.route.own_route_params import OwnRouteParams, OwnRouteRobot
from mrta_agent.runtime.params import Doc
from mrta_zenoh.paramdoc import Check, Duration, NonNegative, Positive, checked, whole

DISCOUNT = 0.95
RESEND_PERIOD = 1.0
SETTLE = 1.0


def _discount(value: float) -> str | None:
    if value <= 0:
        return f"must be > 0, got {value:g}"
    return f"must be in (0, 1], got {value:g}" if value > 1.0 else None


class CbbaKeys(Doc, kw_only=True):
    discount: checked(float, Check("must be a number", _discount)) = DISCOUNT
    bundle_limit: whole(1) | None = None
    resend_period: Duration = RESEND_PERIOD
    settle: Duration = SETTLE
    comm_range: Positive | None = None
    lookahead: NonNegative = 0.0


WHAT = "a CBBA robot parameter file"
KEYS = CbbaKeys


def load_robot(path) -> OwnRouteRobot:
    return own.load_robot(path, WHAT, KEYS)


def load_params(robot_id: str, robot_file, tasks_file, layers_file=None) -> OwnRouteParams:
    return own.load_params(robot_id, robot_file, tasks_file, layers_file, WHAT, KEYS)
