"""Small plane geometry shared by the applications (kept here so they need not import each other)."""

from __future__ import annotations

import math


def rectangle_cells(x0: float, y0: float, x1: float, y1: float,
                    cell: float = 0.5) -> list[tuple[float, float]]:
    """Centres of ~`cell`-long pieces of a rectangle's perimeter, going round it once.

    "Share of the border visited" is the share of these cells someone came near."""
    out: list[tuple[float, float]] = []
    for (ax, ay), (bx, by) in (((x0, y0), (x1, y0)), ((x1, y0), (x1, y1)),
                               ((x1, y1), (x0, y1)), ((x0, y1), (x0, y0))):
        n = max(1, int(math.hypot(bx - ax, by - ay) / cell))
        out += [(ax + (bx - ax) * (i + 0.5) / n, ay + (by - ay) * (i + 0.5) / n) for i in range(n)]
    return out
