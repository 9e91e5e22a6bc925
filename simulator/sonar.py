"""Sonar ranges for every robot at once, with numpy instead of one ray cast per transducer.

Each transducer is a cone (`half_angle` each side of its axis, 7.5° by default, MobileSim's 15°
field of view); its reading is the nearest point of any wall or other robot inside the cone.
Both are exact for our shapes: distance is convex along a segment and over a disc, so the
minimum over (shape ∩ cone) is the unconstrained nearest point when it lies in the cone, or else
lies on a cone edge or a segment end. A single centre ray would miss a robot 2 m ahead between
beams, which no real sonar does. Ranges beyond `max_range` come back as `inf` (no echo); noise
and clipping are the caller's job so this stays a pure geometry function tests check exactly.

Why it scales: the exact cone test is the expensive part, so it runs only on
(transducer, shape) pairs that a cheap, conservative test cannot rule out. Walls are culled per
robot (a wall farther than the sonar's reach from a robot's transducers cannot echo), robots
by their neighbours within reach (every pair's distance up to `KD_TREE_FROM` robots, scipy's
cKDTree from there: importing scipy.spatial was ≈ 0.9 of a 5-robot study run's 3.4 simulator
CPU-s, issue 48) and then per transducer by bearing
(a disc outside the cone's angular window, widened by the transducer's offset from the robot's
centre, cannot be inside it). Culling never changes a reading: every pair it keeps is computed
exactly as without it, and every pair it drops has no point inside the cone within range
(tests/test_sonar.py checks both against brute force).
"""

from __future__ import annotations

import numpy as np

_CHUNK = 1_000_000  # pairs per numpy block: bounds memory for big worlds
_SLACK = 1e-6  # metres added to culling distances: rounding never drops a pair at the edge
KD_TREE_FROM = 256  # robots: below, all N² distances (≈ 0.1 ms at 100) beat a tree's build


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


def _groups(origins: np.ndarray, per_robot: int) -> tuple[np.ndarray, np.ndarray]:
    """Each robot's transducers as one circle: the centre of its origins and their spread."""
    g = origins.reshape(-1, per_robot, 2)
    centre = g.mean(axis=1)
    spread = np.sqrt(((g - centre[:, None, :]) ** 2).sum(axis=2)).max(axis=1)
    return centre, spread


def _ray_segment(fx, fy, dx, dy, ex, ey) -> np.ndarray:
    """Distance along rays (dx, dy) to segments A + s·e, with f = A − O; inf where no hit."""
    denom = dx * ey - dy * ex
    with np.errstate(divide="ignore", invalid="ignore"):
        inv = 1.0 / denom
        t = (fx * ey - fy * ex) * inv
        u = (fx * dy - fy * dx) * inv
    hit = (t >= 0.0) & (u >= 0.0) & (u <= 1.0) & (np.abs(denom) > 1e-12)
    return np.where(hit, t, np.inf)


def _cone_segments(fx, fy, dx, dy, ex, ey, half_angle: float) -> np.ndarray:
    """Nearest point of segments A + s·e (f = A − O) inside cones of axis (dx, dy), element-wise."""
    if half_angle <= 0.0:
        return _ray_segment(fx, fy, dx, dy, ex, ey)
    c, s = np.cos(half_angle), np.sin(half_angle)
    # the axis ray's hit is never nearer than these candidates, so it is not needed
    best = np.minimum(_ray_segment(fx, fy, c * dx + s * dy, -s * dx + c * dy, ex, ey),
                      _ray_segment(fx, fy, c * dx - s * dy, s * dx + c * dy, ex, ey))
    e2 = np.maximum(ex * ex + ey * ey, 1e-18)
    sp = np.clip(-(fx * ex + fy * ey) / e2, 0.0, 1.0)  # nearest point of the segment
    for vx, vy in ((fx + sp * ex, fy + sp * ey), (fx, fy), (fx + ex, fy + ey)):
        dist = np.sqrt(vx * vx + vy * vy)
        inside = vx * dx + vy * dy >= dist * c - 1e-12
        np.minimum(best, np.where(inside, dist, np.inf), out=best)
    return best


def _segment_distance(px, py, walls: np.ndarray) -> np.ndarray:
    """Distance from points (P, 1) to every wall (1, W): the (P, W) matrix."""
    ax, ay = walls[None, :, 0], walls[None, :, 1]
    ex, ey = walls[None, :, 2] - ax, walls[None, :, 3] - ay
    e2 = np.maximum(ex * ex + ey * ey, 1e-18)
    s = np.clip(((px - ax) * ex + (py - ay) * ey) / e2, 0.0, 1.0)
    qx, qy = ax + s * ex - px, ay + s * ey - py
    return np.sqrt(qx * qx + qy * qy)


def ray_walls(origins: np.ndarray, dirs: np.ndarray, walls: np.ndarray, max_range: float,
              half_angle: float = 0.0, per_robot: int = 1) -> np.ndarray:
    """Distance to the nearest wall point inside each cone, `inf` if none within max_range.

    `per_robot`: consecutive origins that belong to one robot (its transducers). Walls are
    culled per robot, then the exact cone test runs on the (transducer, wall) pairs left.
    """
    out = np.full(len(origins), np.inf)
    if len(walls) == 0 or len(origins) == 0:
        return out
    if len(origins) % per_robot:
        raise ValueError(f"{len(origins)} origins are not whole groups of {per_robot}")
    centre, spread = _groups(origins, per_robot)
    step = max(1, _CHUNK // (len(walls) * per_robot))
    for lo in range(0, len(centre), step):
        c = centre[lo:lo + step]
        near = _segment_distance(c[:, 0:1], c[:, 1:2], walls) <= \
            max_range + spread[lo:lo + step, None] + _SLACK
        g, w = np.nonzero(near)
        if len(g) == 0:
            continue
        k = np.arange(per_robot)
        rays = ((g + lo)[:, None] * per_robot + k[None, :]).ravel()
        w = np.repeat(w, per_robot)
        wl = walls[w]
        fx, fy = wl[:, 0] - origins[rays, 0], wl[:, 1] - origins[rays, 1]
        t = _cone_segments(fx, fy, dirs[rays, 0], dirs[rays, 1], wl[:, 2] - wl[:, 0],
                           wl[:, 3] - wl[:, 1], half_angle)
        np.minimum.at(out, rays, t)
    out[out > max_range] = np.inf
    return out


def _ray_circle(ocx, ocy, dx, dy, radius: float) -> np.ndarray:
    """Distance along rays (dx, dy) from O to a circle of `radius` around C, oc = O − C."""
    b = ocx * dx + ocy * dy
    c = ocx * ocx + ocy * ocy - radius * radius
    disc = b * b - c
    with np.errstate(invalid="ignore"):
        t = -b - np.sqrt(disc)
    return np.where((disc >= 0.0) & (t >= 0.0), t, np.inf)


def neighbour_pairs(centres: np.ndarray, reach: float) -> tuple[np.ndarray, np.ndarray]:
    """All ordered pairs (i, j), i ≠ j, no farther apart than `reach` (a k-d tree from
    `KD_TREE_FROM` robots on: ~N·neighbours work). Either way the same set of pairs, and their
    order never matters: each reading is a minimum over the pairs kept."""
    if len(centres) < KD_TREE_FROM:
        d = centres[:, None, :] - centres[None, :, :]
        pairs = np.argwhere(np.triu(np.hypot(d[:, :, 0], d[:, :, 1]) <= reach, k=1))
    else:
        from scipy.spatial import cKDTree  # ≈ 0.9 CPU-s to import: only for big teams
        pairs = cKDTree(centres).query_pairs(reach, output_type="ndarray")
    if len(pairs) == 0:
        empty = np.empty(0, dtype=np.intp)
        return empty, empty
    i = np.concatenate([pairs[:, 0], pairs[:, 1]])
    j = np.concatenate([pairs[:, 1], pairs[:, 0]])
    return i, j


def ray_robots(origins: np.ndarray, dirs: np.ndarray, centres: np.ndarray, radius: float,
               per_robot: int, max_range: float, half_angle: float = 0.0,
               axes: np.ndarray | None = None) -> np.ndarray:
    """Distance to the nearest point of another robot's disc inside each cone, `inf` if none.

    Only pairs of robots within reach are tested, and of those only the transducers whose
    cone can contain the other disc: the cost grows with neighbours, not with N².
    `axes`: the transducers' axis angles in the robot's frame when every robot has that one
    layout (a simulation has one robot model); the bearing test then works in each robot's
    frame, a (pairs × transducers) product of contiguous arrays instead of a gather of every
    pair's directions (≈ 0.6 ms of a 3 ms sweep at 1,000 robots). Either way only the culling
    changes, never a reading: kept pairs are computed from `dirs` exactly.
    """
    n = len(centres)
    out = np.full(len(origins), np.inf)
    if n < 2:
        return out
    # transducers' reach from the centre (one layout: the first robot's says it for all)
    off = origins[:per_robot if axes is not None else None].reshape(-1, per_robot, 2) \
        - centres[:1 if axes is not None else None, None, :]
    rho = float(np.sqrt((off * off).sum(axis=2).max()))
    pi, pj = neighbour_pairs(centres, max_range + radius + rho + _SLACK)
    if len(pi) == 0:
        return out
    # Bearing window: the disc seen from a transducer within rho of i's centre lies within
    # half_angle + asin(r / (D − rho)) + asin(rho / D) of the direction i → j (D = |c_j − c_i|).
    vx, vy = centres[pj, 0] - centres[pi, 0], centres[pj, 1] - centres[pi, 1]
    dist = np.hypot(vx, vy)
    with np.errstate(divide="ignore", invalid="ignore"):
        window = half_angle + np.arcsin(np.minimum(1.0, radius / np.maximum(dist - rho, 1e-12))) \
            + np.arcsin(np.minimum(1.0, rho / np.maximum(dist, 1e-12)))
        ux, uy = vx / dist, vy / dist
    wide = (dist <= radius + rho) | (window >= np.pi)  # overlapping or very close: test all
    threshold = np.cos(np.minimum(window, np.pi)) - 1e-12
    if axes is None:
        # robot i's K directions gathered as one row per pair (a 2-D gather per coordinate
        # of (P, K) computed indices cost 3× as much at 1,000 robots)
        d = dirs.reshape(n, per_robot, 2)[pi]              # (P, K, 2)
        cos_bearing = d[:, :, 0] * ux[:, None] + d[:, :, 1] * uy[:, None]
    else:
        # i → j turned into the frame of i's first transducer (its direction is dirs[i·K]),
        # against each transducer's axis in that frame: d_ik · u = e_k · R(−φ_i) u
        first = dirs[pi * per_robot]
        wx = ux * first[:, 0] + uy * first[:, 1]
        wy = uy * first[:, 0] - ux * first[:, 1]
        rel = np.asarray(axes, dtype=float) - float(axes[0])
        cos_bearing = wx[:, None] * np.cos(rel)[None, :] + wy[:, None] * np.sin(rel)[None, :]
    # `wide` by itself, not as a −inf threshold: robots at one centre have no bearing (NaN)
    pair, k = np.nonzero(wide[:, None] | (cos_bearing >= threshold[:, None]))
    if len(pair) == 0:
        return out
    rays = pi[pair] * per_robot + k
    other = pj[pair]
    cox = centres[other, 0] - origins[rays, 0]  # origin → centre
    coy = centres[other, 1] - origins[rays, 1]
    dx, dy = dirs[rays, 0], dirs[rays, 1]
    dist_c = np.hypot(cox, coy)
    if half_angle > 0.0:
        # nearest point of the disc, if its direction lies in the cone; else a cone edge
        c, s = np.cos(half_angle), np.sin(half_angle)
        inside = cox * dx + coy * dy >= dist_c * c - 1e-12
        t = np.where(inside, dist_c - radius, np.inf)
        np.minimum(t, _ray_circle(-cox, -coy, c * dx - s * dy, s * dx + c * dy, radius), out=t)
        np.minimum(t, _ray_circle(-cox, -coy, c * dx + s * dy, -s * dx + c * dy, radius), out=t)
    else:
        t = _ray_circle(-cox, -coy, dx, dy, radius)
    t = np.where(dist_c <= radius, 0.0, t)  # origin inside another body (overlap): touching
    hit = np.isfinite(t) & (t <= max_range)
    np.minimum.at(out, rays[hit], np.maximum(t[hit], 0.0))
    return out
