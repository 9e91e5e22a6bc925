"""Sane ranges for every duration, rate, timeout and coordinate a user can write down.

Finite is not enough: a `timeout_duration` of 1e308 s, a wall at x = 1e308 m, a monitor
`<timeout>` of 1e308 or an experiment `duration: 1e308` are all finite, and each either hangs a
process for good or overflows the arithmetic downstream. Every file reader and the
validators check values against the one table below, so a value the runtime would refuse is
refused by `mrta arch validate` / `mrta app validate` too, with the file, the line and the range.

The ranges are generous on purpose (what a real fleet needs, times a large margin); they exist
to catch typos and hostile files, not to second-guess a design. docs/toolchain.md ("Ranges")
lists them; `ranges_table()` writes that table, so the two cannot drift apart.
"""

from __future__ import annotations

import math
from dataclasses import dataclass


@dataclass(frozen=True)
class Range:
    """A closed interval [low, high] in `unit`, with a reason a user can read."""

    low: float
    high: float
    unit: str
    why: str

    def text(self) -> str:
        unit = f" {self.unit}" if self.unit else ""
        return f"between {_g(self.low)} and {_g(self.high)}{unit}"

    def problem(self, value: float) -> str | None:
        """Why `value` is out of range (or not a finite number), None when it is fine."""
        if type(value) is bool or not isinstance(value, (int, float)):
            return f"expected a number {self.text()}, got {value!r:.40}"
        if not math.isfinite(value):
            return f"expected a finite number {self.text()}, got {value}"
        if not self.low <= value <= self.high:
            return f"must be {self.text()} ({self.why}), got {_g(value)}"
        return None

    def check(self, value: float, what: str) -> float:
        """`value` as a float, or ValueError naming `what` and the range."""
        problem = self.problem(value)
        if problem is not None:
            raise ValueError(f"{what} {problem}")
        return float(value)


def _g(x: float) -> str:
    """Numbers as people write them: 86400 not 8.64e+04, 0.001, 1e+308."""
    if isinstance(x, int):
        return f"{x}"
    if x == int(x) and abs(x) < 1e15:
        return f"{int(x)}"
    return f"{x:g}"


DAY = 86_400.0

# Durations, delays and timeouts (seconds): a millisecond to a day. A tick shorter than a
# millisecond is not honoured by any process here; a timeout longer than a day is a typo.
DURATION = Range(0.001, DAY, "s", "a millisecond to a day")
# A run's length (mission, experiment, replay gaps): up to a week of simulated time.
RUN_DURATION = Range(0.001, 7 * DAY, "s", "a millisecond to a week")
# Rates (Hz): a tick every 100 s to a busy loop's 1 kHz.
RATE = Range(0.01, 1000.0, "Hz", "a tick every 100 s to 1 kHz")
# Coordinates (metres): the simulator's world is at most 10 km from its origin (pymunk works in
# floats; a wall at 1e308 m makes every ray cast overflow).
COORDINATE = Range(-10_000.0, 10_000.0, "m", "10 km either side of the origin")
# ALLIANCE motivation units: θ, and the impatience rates added to the motivation per tick.
THRESHOLD = Range(0.001, 1e6, "", "motivation units")
IMPATIENCE = Range(1e-6, 1e6, "per tick", "motivation units added per tick")
# Dimensionless weights and levels (MURDOCH's utility): a factor of a million either way.
WEIGHT = Range(-1e6, 1e6, "", "a factor of a million")
LEVEL = Range(0.0, 1e6, "", "0 or more, up to a million")
# Monitor queue sizes (samples kept per subscription).
QUEUE_SIZE = Range(1, 100_000, "samples", "one to a hundred thousand")
# Seeds: non-negative 63-bit integers (one CSV cell, one numpy SeedSequence entropy).
SEED = Range(0, 2**63 - 1, "", "a non-negative 63-bit integer")
# Runs an experiment starts unless --max-runs says otherwise.
MAX_RUNS = 10_000

TABLE = (
    ("durations, delays, timeouts (ALLIANCE `timeout_duration`, `buffer_horizon`, "
     "`task_expected_duration`, `yielding_delay`, `giving_up_delay`, "
     "`max_expected_duration`; MURDOCH `bid_window`, `renewal_period`, `lease_timeout`, "
     "`reannounce_period`, `give_up_delay`; sensors' `timeout_duration`, `buffer_horizon`; "
     "a monitor's `<timeout>`)", DURATION),
    ("an experiment's `duration` (simulated seconds); `mrta replay --max-gap`", RUN_DURATION),
    ("rates (`spin_rate`, `broadcast_rate`, `control_rate`)", RATE),
    ("coordinates (world walls, start poses, border, MURDOCH task locations; a MobileSim "
     "map's millimetres once converted)", COORDINATE),
    ("ALLIANCE `threshold`", THRESHOLD),
    ("ALLIANCE `fast_rate`", IMPATIENCE),
    ("MURDOCH utility weights", WEIGHT),
    ("MURDOCH skill `level`", LEVEL),
    ("a monitor's `<queue_size>`", QUEUE_SIZE),
    ("seeds", SEED),
)


def ranges_table() -> str:
    """The Markdown table docs/toolchain.md shows (a test keeps the two equal)."""
    lines = ["| value | range | why |", "| --- | --- | --- |"]
    for what, r in TABLE:
        unit = f" {r.unit}" if r.unit else ""
        lines.append(f"| {what} | {_g(r.low)} – {_g(r.high)}{unit} | {r.why} |")
    lines.append(f"| runs of one experiment | at most {MAX_RUNS:,} unless `--max-runs` "
                 "raises it | a typo in a list must not start a million runs |")
    return "\n".join(lines)
