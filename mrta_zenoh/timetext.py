"""A stamp as a log line shows it: "at t=12.34" for simulated seconds, "at 14:03:12.53" (local
time of day) for a wall-clock stamp, so an agent on wall time does not log
`at t=1795715420.53`.

The two are told apart by size, which is unambiguous for any clock this project runs: wall
stamps are seconds since 1970, past WALL_FROM (September 2001), while a simulated run lasts at
most a week (limits.RUN_DURATION) and a clock restarts from 0 with each run.
"""

from __future__ import annotations

import time

WALL_FROM = 1e9


def at(t: float) -> str:
    """`at t=12.34` (simulated seconds) or `at 14:03:12.53` (a wall-clock stamp, local time)."""
    if t < WALL_FROM:
        return f"at t={t:.2f}"
    cents = round(t * 100)  # to the hundredth, as simulated stamps are shown
    return f"at {time.strftime('%H:%M:%S', time.localtime(cents // 100))}.{cents % 100:02d}"
