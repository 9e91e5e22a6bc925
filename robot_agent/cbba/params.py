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

from dataclasses import dataclass

from mrta_agent.route import own_route_params as own
from mrta_agent.route.own_route_params import OwnRouteParams, OwnRouteRobot, lookahead
from mrta_agent.runtime.params import StrictMapping

DISCOUNT = 0.95
RESEND_PERIOD = 1.0
SETTLE = 1.0


@dataclass(frozen=True)
class CbbaKeys:
    discount: float = DISCOUNT
    bundle_limit: int | None = None
    resend_period: float = RESEND_PERIOD
    settle: float = SETTLE
    comm_range: float | None = None
    lookahead: float = 0.0


def read_keys(top: StrictMapping) -> CbbaKeys:
    discount = top.get("discount", float, DISCOUNT, positive=True)
    if discount > 1.0:
        raise top.doc.error(("discount",), f"discount must be in (0, 1], got {discount:g}")
    limit = top.data.get("bundle_limit")
    if limit is not None and (type(limit) is not int or limit < 1):
        raise top.doc.error(("bundle_limit",), f"bundle_limit must be a whole number ≥ 1, got "
                            f"{limit!r:.40}")
    comm = top.get("comm_range", float, None, positive=True)
    return CbbaKeys(discount, limit, top.duration("resend_period", RESEND_PERIOD),
                    top.duration("settle", SETTLE), comm, lookahead(top))


WHAT = "a CBBA robot parameter file"
KEYS = set(CbbaKeys.__dataclass_fields__)


def load_robot(path) -> OwnRouteRobot:
    return own.load_robot(path, WHAT, KEYS, read_keys)


def load_params(robot_id: str, robot_file, tasks_file, layers_file=None) -> OwnRouteParams:
    return own.load_params(robot_id, robot_file, tasks_file, layers_file, WHAT, KEYS, read_keys)
