"""Patrol's own metrics of a run, from its recording: collisions and the share of the border
visited (the mission hook, mission.py, adds them to every run's summary)."""

from __future__ import annotations

import math

from mrta_zenoh.codec import DecodeError, decode, type_from_encoding

from .ledger import rectangle_cells


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
