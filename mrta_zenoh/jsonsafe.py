"""JSON text that is always valid: RFC 8259 has no NaN or Infinity, and a line-per-sample
consumer (`jq`, a dashboard) must never be handed one. Python's `json` writes `NaN` by default
and raises with `allow_nan=False`; here a non-finite float is replaced, by what the caller
chooses (`mrta echo` keeps it readable as a string, the supervisor's snapshot writes null)."""

from __future__ import annotations

import json
import math
from typing import Any, Callable


def dumps(value: Any, nonfinite: Callable[[float], Any], default: Callable | None = None) -> str:
    return json.dumps(_finite(value, nonfinite), default=default, allow_nan=False)


def _finite(v: Any, nonfinite: Callable[[float], Any]) -> Any:
    if isinstance(v, float) and not math.isfinite(v):
        return nonfinite(v)
    if isinstance(v, dict):
        return {k: _finite(x, nonfinite) for k, x in v.items()}
    if isinstance(v, (list, tuple)):
        return [_finite(x, nonfinite) for x in v]
    return v
