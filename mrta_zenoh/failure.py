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
from .limits import RUN_DURATION
from .yamlfile import did_you_mean

_SPEC = re.compile(rf"^({ID_PATTERN})@(\d+(?:\.\d+)?)$")
USAGE = "ROBOT@SECONDS, e.g. robot2@30"


class Failure(NamedTuple):
    robot: str
    at: float
    spec: str  # as written: what is passed on, so the next hop reads exactly the same value


def failure_problem(failure: Failure, robots, duration: float) -> str | None:
    """Why `failure` cannot happen in a run of `robots` lasting `duration` simulated seconds
    (a robot the application does not have, a time at or after the end), or None. One check
    for every hop: an experiment's `failures` (at load, naming the line: before, every run
    failed the same way), the mission's `--fail`."""
    robots = list(robots)
    if failure.robot not in robots:
        return (f"{failure.spec}: {failure.robot} is not one of the application's robots "
                f"({', '.join(robots) or 'none'})" + did_you_mean(failure.robot, robots))
    if failure.at >= duration:
        return f"{failure.spec}: {failure.at:g} s is not before the end of the run ({duration:g} s)"
    return None


def parse_failure(text: str) -> Failure:
    """ValueError (saying what is expected) for anything but ROBOT@SECONDS with SECONDS > 0."""
    m = _SPEC.match(text)
    if m is None or float(m[2]) <= 0:
        raise ValueError(f"{text!r:.80}: expected {USAGE} (seconds > 0)")
    problem = RUN_DURATION.problem(float(m[2]))  # 1e308 is > 0 too, but no run lasts that long
    if problem is not None:
        raise ValueError(f"{text!r:.80}: the time {problem}")
    return Failure(m[1], float(m[2]), text)
