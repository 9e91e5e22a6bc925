"""ROBOT@SECONDS: which robot fails, and when (simulated seconds).

One grammar for every hop the spec makes: an experiment's `failures` list, a mission's `--fail`,
the agent's `$MRTA_CRASH`. Each used to parse it its own way (a regular expression, `float()`
with a bound, `float()` without), so an experiment accepted `robot2@0`, which the demo then
refused in every run. The strictest of the three is kept: the robot is an id as keys carry it
(`keys.ID_PATTERN`), the seconds a plain decimal (no sign, no exponent) greater than zero.
"""

from __future__ import annotations

import re
from typing import NamedTuple

from .keys import ID_PATTERN

_SPEC = re.compile(rf"^({ID_PATTERN})@(\d+(?:\.\d+)?)$")
USAGE = "ROBOT@SECONDS, e.g. robot2@30"


class Failure(NamedTuple):
    robot: str
    at: float
    spec: str  # as written: what is passed on, so the next hop reads exactly the same value


def parse_failure(text: str) -> Failure:
    """ValueError (saying what is expected) for anything but ROBOT@SECONDS with SECONDS > 0."""
    m = _SPEC.match(text)
    if m is None or float(m[2]) <= 0:
        raise ValueError(f"{text!r:.80}: expected {USAGE} (seconds > 0)")
    return Failure(m[1], float(m[2]), text)
