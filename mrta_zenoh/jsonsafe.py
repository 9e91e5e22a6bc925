"""JSON text that is always valid and reads as people write numbers.

* RFC 8259 has no NaN or Infinity, and a line-per-sample consumer (`jq`, a dashboard) must
  never be handed one. Python's `json` writes `NaN` by default and raises with
  `allow_nan=False`; here a non-finite float is replaced, by what the caller chooses (`mrta
  echo` keeps it readable as a string, the supervisor's snapshot writes null).
* Float noise is dropped: `51.62` computed as 51.6 + 0.02 is the double 51.620000000000005,
  which Python prints in full. Every float is written as the shortest text of its value rounded
  to 15 significant digits — the decimal precision a double always carries (DBL_DIG) — so
  nothing a sender meant is lost, only the last binary digit's noise: 51.62, 0.3, 1795480671.6.
"""

from __future__ import annotations

import json
import math
from typing import Any, Callable

DIGITS = 15  # DBL_DIG: any decimal of up to 15 significant digits survives a double


def tidy(x: float) -> float:
    """`x` rounded to DIGITS significant digits (its repr is then the short one) — or `x` itself
    where rounding up would overflow to infinity (1.7976931348623157e+308, the largest double)."""
    t = float(f"{x:.{DIGITS}g}")
    return t if math.isfinite(t) else x


def tidy_all(value: Any) -> Any:
    """`value` with every finite float in it tidied (non-finite ones kept): for YAML and plain
    text, which should not show float noise either."""
    return _finite(value, lambda v: v)


def dumps(value: Any, nonfinite: Callable[[float], Any], default: Callable | None = None) -> str:
    return json.dumps(_finite(value, nonfinite), default=default, allow_nan=False)


def _finite(v: Any, nonfinite: Callable[[float], Any]) -> Any:
    if isinstance(v, float):
        return tidy(v) if math.isfinite(v) else nonfinite(v)
    if isinstance(v, dict):
        return {k: _finite(x, nonfinite) for k, x in v.items()}
    if isinstance(v, (list, tuple)):
        return [_finite(x, nonfinite) for x in v]
    return v
