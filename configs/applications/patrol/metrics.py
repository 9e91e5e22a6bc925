"""Mission metrics of a patrol run, from its recording: who did what, coverage, collisions,
share of the border visited. Used by `mrta demo` (and any experiment over patrol runs)."""

from __future__ import annotations

import math

from mrta_zenoh.codec import DecodeError, decode, type_from_encoding

from .ledger import rectangle_cells


def coverage(intervals: dict, tasks: list[str], t0: float, t1: float, step: float = 0.1) -> dict:
    """Per task: share of [t0, t1] with exactly one robot on it, none, more than one."""
    out = {}
    n = max(1, int((t1 - t0) / step))
    for task in tasks:
        spans = [(a, b) for iv in intervals.values() for tk, a, b in iv if tk == task]
        one = none = many = 0
        for k in range(n):
            t = t0 + (k + 0.5) * step
            c = sum(1 for a, b in spans if a <= t < b)
            one += c == 1
            none += c == 0
            many += c > 1
        out[task] = {"exactly_one": round(one / n, 3), "none": round(none / n, 3),
                     "more_than_one": round(many / n, 3)}
    return out


def mission_metrics(records, border: tuple[float, float, float, float], reach: float) -> dict:
    """Collisions (from the simulator's bumper counters) and the share of the border visited."""
    collisions: dict[str, int] = {}
    x0, y0, x1, y1 = border
    cells = rectangle_cells(x0, y0, x1, y1, 0.5)
    visited = [False] * len(cells)
    for key, enc, _t, payload in records:
        robot, _, topic = key.partition("/")
        if topic not in ("bumper", "ground_truth"):
            continue
        try:
            msg = decode(type_from_encoding(enc), payload)
        except DecodeError:
            continue
        if topic == "bumper":
            collisions[robot] = max(collisions.get(robot, 0), msg.collisions)
        else:
            px, py = msg.pose.x, msg.pose.y
            for i, (cx, cy) in enumerate(cells):
                if not visited[i] and abs(cx - px) <= reach and abs(cy - py) <= reach \
                        and math.hypot(cx - px, cy - py) <= reach:
                    visited[i] = True
    return {"collisions": collisions, "collisions_total": sum(collisions.values()),
            "border_visited": round(sum(visited) / len(cells), 3) if cells else 0.0}
