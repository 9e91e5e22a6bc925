"""Sonar ranges for every robot at once, with numpy instead of one ray cast per transducer.

Each transducer is a cone (`half_angle` each side of its axis, 7.5° by default, MobileSim's 15°
field of view); its reading is the nearest point of any wall or other robot inside the cone.
Both are exact for our shapes: distance is convex along a segment and over a disc, so the
minimum over (shape ∩ cone) is the unconstrained nearest point when it lies in the cone, or else
lies on a cone edge or a segment end. A single centre ray would miss a robot 2 m ahead between
beams, which no real sonar does. Ranges beyond `max_range` come back as `inf` (no echo); noise
and clipping are the caller's job so this stays a pure geometry function tests check exactly.
"""

from __future__ import annotations

import numpy as np

_CHUNK = 1_000_000  # rays × shapes per numpy block: bounds memory for big worlds


def sonar_origins(poses: np.ndarray, sonars: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """World-frame origins (N*K, 2) and unit directions (N*K, 2) for robots at `poses` (N, 3)."""
    c, s = np.cos(poses[:, 2:3]), np.sin(poses[:, 2:3])  # (N, 1)
    sx, sy = sonars[None, :, 0], sonars[None, :, 1]     # (1, K)
    ox = poses[:, 0:1] + c * sx - s * sy
    oy = poses[:, 1:2] + s * sx + c * sy
    ang = poses[:, 2:3] + sonars[None, :, 2]
    origins = np.stack([ox, oy], axis=-1).reshape(-1, 2)
    dirs = np.stack([np.cos(ang), np.sin(ang)], axis=-1).reshape(-1, 2)
    return origins, dirs


def _rotate(d: np.ndarray, angle: float) -> np.ndarray:
    c, s = np.cos(angle), np.sin(angle)
    return np.stack([c * d[..., 0] - s * d[..., 1], s * d[..., 0] + c * d[..., 1]], axis=-1)


def _in_cone(v: np.ndarray, dist: np.ndarray, d: np.ndarray, cos_half: float) -> np.ndarray:
    return (v[..., 0] * d[..., 0] + v[..., 1] * d[..., 1]) >= dist * cos_half - 1e-12


def _ray_segment(fx, fy, dx, dy, ex, ey) -> np.ndarray:
    """Distance along rays (dx, dy) to segments A + s·e, with f = A − O; inf where no hit."""
    denom = dx * ey - dy * ex
    with np.errstate(divide="ignore", invalid="ignore"):
        inv = 1.0 / denom
        t = (fx * ey - fy * ex) * inv
        u = (fx * dy - fy * dx) * inv
    hit = (t >= 0.0) & (u >= 0.0) & (u <= 1.0) & (np.abs(denom) > 1e-12)
    return np.where(hit, t, np.inf)


def ray_walls(origins: np.ndarray, dirs: np.ndarray, walls: np.ndarray, max_range: float,
              half_angle: float = 0.0) -> np.ndarray:
    """Distance to the nearest wall point inside each cone, `inf` if none within max_range.

    Written component by component on (rays, walls) arrays: at 10 robots this function is most
    of a sensor update, and every temporary counts.
    """
    out = np.full(len(origins), np.inf)
    if len(walls) == 0 or len(origins) == 0:
        return out
    ax, ay = walls[None, :, 0], walls[None, :, 1]
    ex, ey = walls[None, :, 2] - ax, walls[None, :, 3] - ay
    e2 = np.maximum(ex * ex + ey * ey, 1e-18)
    cos_half, c, s = np.cos(half_angle), np.cos(half_angle), np.sin(half_angle)
    step = max(1, _CHUNK // len(walls))
    for lo in range(0, len(origins), step):
        ox, oy = origins[lo:lo + step, 0:1], origins[lo:lo + step, 1:2]
        dx, dy = dirs[lo:lo + step, 0:1], dirs[lo:lo + step, 1:2]
        fx, fy = ax - ox, ay - oy  # A − O, (R, W)
        if half_angle <= 0.0:
            best = _ray_segment(fx, fy, dx, dy, ex, ey)
        else:
            # the axis ray's hit is never nearer than these candidates, so it is not needed
            best = np.minimum(_ray_segment(fx, fy, c * dx + s * dy, -s * dx + c * dy, ex, ey),
                              _ray_segment(fx, fy, c * dx - s * dy, s * dx + c * dy, ex, ey))
            sp = np.clip(-(fx * ex + fy * ey) / e2, 0.0, 1.0)  # nearest point of the segment
            for vx, vy in ((fx + sp * ex, fy + sp * ey), (fx, fy), (fx + ex, fy + ey)):
                dist = np.sqrt(vx * vx + vy * vy)
                inside = vx * dx + vy * dy >= dist * cos_half - 1e-12
                np.minimum(best, np.where(inside, dist, np.inf), out=best)
        row = best.min(axis=1)
        out[lo:lo + step] = np.where(row <= max_range, row, np.inf)
    return out


def _ray_circle(oc: np.ndarray, d: np.ndarray, radius: float) -> np.ndarray:
    b = np.einsum("ij,ij->i", oc, d)
    c = np.einsum("ij,ij->i", oc, oc) - radius * radius
    disc = b * b - c
    with np.errstate(invalid="ignore"):
        t = -b - np.sqrt(disc)
    return np.where((disc >= 0.0) & (t >= 0.0), t, np.inf)


def _pairs_within(centres: np.ndarray, reach: float) -> tuple[np.ndarray, np.ndarray]:
    """All ordered pairs (i, j), i ≠ j, closer than `reach`: a sweep along x, not N² distances."""
    n = len(centres)
    order = np.argsort(centres[:, 0], kind="stable")
    xs = centres[order, 0]
    lo = np.searchsorted(xs, xs - reach, side="left")
    hi = np.searchsorted(xs, xs + reach, side="right")
    counts = hi - lo
    a = np.repeat(np.arange(n), counts)
    starts = np.repeat(lo - np.concatenate(([0], np.cumsum(counts)[:-1])), counts)
    b = np.arange(counts.sum()) + starts
    i, j = order[a], order[b]
    diff = centres[i] - centres[j]
    keep = (i != j) & ((diff * diff).sum(axis=1) < reach * reach)
    return i[keep], j[keep]


def ray_robots(origins: np.ndarray, dirs: np.ndarray, centres: np.ndarray, radius: float,
               per_robot: int, max_range: float, half_angle: float = 0.0) -> np.ndarray:
    """Distance to the nearest point of another robot's disc inside each cone, `inf` if none.

    Only pairs of robots closer than max_range + 2·radius are tested, so the cost grows with
    neighbours rather than with N² cone tests.
    """
    n = len(centres)
    out = np.full(len(origins), np.inf)
    if n < 2:
        return out
    pi, pj = _pairs_within(centres, max_range + 2.0 * radius)
    if len(pi) == 0:
        return out
    k = np.arange(per_robot)
    rays = (pi[:, None] * per_robot + k[None, :]).ravel()  # (P*K,)
    other = np.repeat(pj, per_robot)
    co = centres[other] - origins[rays]  # origin → centre
    d = dirs[rays]
    dist_c = np.hypot(co[:, 0], co[:, 1])
    if half_angle > 0.0:
        # nearest point of the disc, if its direction lies in the cone; else a cone edge
        near = np.where(_in_cone(co, dist_c, d, np.cos(half_angle)), dist_c - radius, np.inf)
        t = np.minimum(near, np.minimum(_ray_circle(-co, _rotate(d, half_angle), radius),
                                        _ray_circle(-co, _rotate(d, -half_angle), radius)))
    else:
        t = _ray_circle(-co, d, radius)
    t = np.where(dist_c <= radius, 0.0, t)  # origin inside another body (overlap): touching
    hit = np.isfinite(t) & (t <= max_range)
    np.minimum.at(out, rays[hit], np.maximum(t[hit], 0.0))
    return out
