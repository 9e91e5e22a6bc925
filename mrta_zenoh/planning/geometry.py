"""Shortest drivable paths around walls: a visibility graph over the walls' inflated outlines.

A robot of radius r collides with a wall segment exactly when its centre enters the wall's
*capsule* (every point within r of the segment). So each wall is inflated by `clearance` (the
robot's radius plus a margin: `CLEARANCE`) into a convex polygon that contains its capsule — the
hull of two regular `SIDES`-gons circumscribing the discs at the wall's ends — and the robot's
centre must stay outside every polygon's interior. The shortest such path bends only at polygon
corners, so it is a shortest path in the graph whose nodes are the corners (those not inside
another obstacle) plus the two end points, and whose edges are the straight segments that cross
no obstacle's interior (touching an outline is allowed: the outline already keeps the margin).
Dijkstra's algorithm on that graph gives the path and its length.

Why a polygon and not the exact capsule: the capsule's shortest paths follow arcs, which a
robot drives no better than the polygon's short chords, and straight legs keep the path a list
of waypoints for the delivery layer to drive (`configs/applications/delivery/layers.py`). The
polygon is at most clearance · (1/cos(π/SIDES) − 1) ≈ 3 cm longer per corner (0.4 m, 8 sides).

Pure Python (an agent builds one at start and plans each task's path on it).
"""

from __future__ import annotations

import heapq
import math
from dataclasses import dataclass, field
from typing import Sequence

from ..errors import ConfigError
from .problem import Point

ROBOT_RADIUS = 0.26      # m: the simulator's P3-DX model (it contains every sonar transducer)
MARGIN = 0.14            # m: room for the robot's tracking error around a corner
CLEARANCE = ROBOT_RADIUS + MARGIN
SIDES = 8
ON_OUTLINE = 1e-7     # m: a point this close to an outline is on it, not inside
SLIVER = 1e-9         # of a segment's length: an overlap this short is a touch, not a crossing

Segment = tuple[float, float, float, float]


def _cross(ox: float, oy: float, ax: float, ay: float, bx: float, by: float) -> float:
    return (ax - ox) * (by - oy) - (ay - oy) * (bx - ox)


def _hull(points: list[Point]) -> list[Point]:
    """The convex hull, counter-clockwise (Andrew's monotone chain)."""
    pts = sorted(set(points))
    if len(pts) <= 2:
        return pts
    lower: list[Point] = []
    for p in pts:
        while len(lower) >= 2 and _cross(*lower[-2], *lower[-1], *p) <= 0:
            lower.pop()
        lower.append(p)
    upper: list[Point] = []
    for p in reversed(pts):
        while len(upper) >= 2 and _cross(*upper[-2], *upper[-1], *p) <= 0:
            upper.pop()
        upper.append(p)
    return lower[:-1] + upper[:-1]


@dataclass(frozen=True, eq=False)
class Obstacle:
    """A wall inflated to a convex polygon (counter-clockwise corners). Its edges are kept as
    half-planes (a, b, c): a point x lies `a·x₀ + b·x₁ + c` inside the edge's line."""

    corners: tuple[Point, ...]
    box: tuple[float, float, float, float] = field(init=False)
    planes: tuple[tuple[float, float, float], ...] = field(init=False)

    def __post_init__(self) -> None:
        xs, ys = [c[0] for c in self.corners], [c[1] for c in self.corners]
        object.__setattr__(self, "box", (min(xs), min(ys), max(xs), max(ys)))
        c = self.corners
        object.__setattr__(self, "planes", tuple(_plane(c[k], c[(k + 1) % len(c)])
                                                 for k in range(len(c))))

    @classmethod
    def around(cls, wall: Segment, clearance: float) -> "Obstacle":
        x1, y1, x2, y2 = wall
        r = clearance / math.cos(math.pi / SIDES)
        ring = [(r * math.cos(2 * math.pi * (k + 0.5) / SIDES),
                 r * math.sin(2 * math.pi * (k + 0.5) / SIDES)) for k in range(SIDES)]
        return cls(tuple(_hull([(x + dx, y + dy) for x, y in ((x1, y1), (x2, y2))
                                for dx, dy in ring])))

    def contains(self, p: Point, eps: float = ON_OUTLINE) -> bool:
        """Whether p lies strictly inside (more than eps from the outline)."""
        x, y = p
        return all(a * x + b * y + c > eps for a, b, c in self.planes)

    def blocks(self, a: Point, b: Point) -> bool:
        """Whether the segment a–b crosses the interior (Cyrus–Beck clipping against the
        half-planes, each shrunk by a tolerance so that a segment along an edge passes)."""
        x0, y0, x1, y1 = self.box
        ax, ay = a
        bx, by = b
        if (max(ax, bx) <= x0 or min(ax, bx) >= x1 or max(ay, by) <= y0
                or min(ay, by) >= y1):
            return False
        t_in, t_out = 0.0, 1.0
        for pa, pb, pc in self.planes:
            da = pa * ax + pb * ay + pc - ON_OUTLINE
            db = pa * bx + pb * by + pc - ON_OUTLINE
            if da <= 0 and db <= 0:
                return False
            if da < 0 or db < 0:
                t = da / (da - db)
                if da < 0:
                    t_in = max(t_in, t)
                else:
                    t_out = min(t_out, t)
                if t_in >= t_out - SLIVER:
                    return False
        return t_in < t_out - SLIVER


def _plane(p: Point, q: Point) -> tuple[float, float, float]:
    """The edge p→q of a counter-clockwise polygon as (a, b, c): a·x + b·y + c is how far x lies
    on its inner (left) side."""
    ex, ey = q[0] - p[0], q[1] - p[1]
    n = math.hypot(ex, ey)
    return (-ey / n, ex / n, (ey * p[0] - ex * p[1]) / n)


class PathMap:
    """Shortest drivable paths among `walls` for a robot needing `clearance` around it."""

    def __init__(self, walls: Sequence[Segment], clearance: float = CLEARANCE):
        if not (math.isfinite(clearance) and clearance > 0):
            raise ConfigError(f"clearance must be a finite number > 0, got {clearance!r}")
        self.walls = tuple(tuple(float(v) for v in w) for w in walls)
        self.clearance = clearance
        self.obstacles = [Obstacle.around(w, clearance) for w in self.walls]
        self.nodes: list[Point] = []
        # each node's two neighbours on its polygon: whether a line through it is tangent
        self._sides: list[tuple[Point, Point]] = []
        for k, o in enumerate(self.obstacles):
            c = o.corners
            for i, corner in enumerate(c):
                if not any(p.contains(corner) for m, p in enumerate(self.obstacles) if m != k):
                    self.nodes.append(corner)
                    self._sides.append((c[i - 1], c[(i + 1) % len(c)]))
        self._edges: list[list[tuple[int, float]]] | None = None

    @property
    def edges(self) -> list[list[tuple[int, float]]]:
        """The visibility graph's edges, built on first use: checking where points may be
        (`check_point`, an instance's validation) needs none of it.

        Only *bitangent* edges: a shortest path bends at a corner only by wrapping round its
        polygon, so each of its legs lies on a line that leaves the polygon at either end wholly
        on one side (a supporting line; Latombe, *Robot Motion Planning*, 1991, §4.1, the
        reduced visibility graph). The other pairs are never on a shortest path and are not
        tested for visibility — most of the pairs, and the visibility tests are the cost."""
        if self._edges is None:
            n = len(self.nodes)
            edges: list[list[tuple[int, float]]] = [[] for _ in range(n)]
            for i in range(n):
                a = self.nodes[i]
                for j in range(i + 1, n):
                    b = self.nodes[j]
                    if self._tangent(i, b) and self._tangent(j, a) and self.visible(a, b):
                        d = math.dist(a, b)
                        edges[i].append((j, d))
                        edges[j].append((i, d))
            self._edges = edges
        return self._edges

    def _tangent(self, i: int, p: Point) -> bool:
        """Whether the line from node i towards p supports node i's polygon (its two
        neighbouring corners not strictly on opposite sides; a leg along an edge counts)."""
        (cx, cy), ((ux, uy), (wx, wy)) = self.nodes[i], self._sides[i]
        dx, dy = p[0] - cx, p[1] - cy
        s1 = dx * (uy - cy) - dy * (ux - cx)
        s2 = dx * (wy - cy) - dy * (wx - cx)
        eps = ON_OUTLINE * math.hypot(dx, dy)
        return not ((s1 > eps and s2 < -eps) or (s1 < -eps and s2 > eps))

    def visible(self, a: Point, b: Point, skip: Sequence[Obstacle] = ()) -> bool:
        return not any(o.blocks(a, b) for o in self.obstacles if o not in skip)

    def check_point(self, p: Point, what: str) -> None:
        """ConfigError when a robot's centre cannot be at p (too close to a wall)."""
        for w, o in zip(self.walls, self.obstacles):
            if o.contains(p):
                raise ConfigError(
                    f"{what} at ({p[0]:g}, {p[1]:g}) is closer than {self.clearance:g} m (a "
                    f"robot's radius and margin) to the wall {list(w)}: no robot can be there")

    def _seen(self, p: Point, skip: Sequence[Obstacle] = ()) -> list[tuple[int, float]]:
        """The corners visible from p on a line tangent to their polygon (a shortest path's
        first or last leg: `edges`), with their distances."""
        return [(i, math.dist(p, c)) for i, c in enumerate(self.nodes)
                if self._tangent(i, p) and self.visible(p, c, skip)]

    def _search(self, seen: list[tuple[int, float]]) -> tuple[list[float], list[int]]:
        """Dijkstra over the corners from a point that sees `seen`: (distance, predecessor;
        −1: the point itself)."""
        dist = [math.inf] * len(self.nodes)
        prev = [-1] * len(self.nodes)
        for i, d in seen:
            dist[i] = d
        heap = [(d, i) for i, d in seen]
        heapq.heapify(heap)
        while heap:
            d, i = heapq.heappop(heap)
            if d > dist[i]:
                continue
            for j, w in self.edges[i]:
                if d + w < dist[j]:
                    dist[j], prev[j] = d + w, i
                    heapq.heappush(heap, (d + w, j))
        return dist, prev

    @staticmethod
    def _last(dist: list[float], seen_b: list[tuple[int, float]]) -> tuple[float, int]:
        """The shortest total to b through the corners b sees, and that corner (−1: none)."""
        best, last = math.inf, -1
        for i, d in seen_b:
            if dist[i] + d < best:
                best, last = dist[i] + d, i
        return best, last

    def _unreachable(self, a: Point, b: Point) -> ConfigError:
        return ConfigError(f"no drivable path from ({a[0]:g}, {a[1]:g}) to ({b[0]:g}, "
                           f"{b[1]:g}): walls close it off")

    def path(self, a: Point, b: Point) -> list[Point]:
        """The waypoints of a shortest drivable path from a to b, both included.

        A start inside an obstacle's margin (a robot that drifted a few centimetres past an
        outline on its way round a corner) may leave it: that obstacle does not block the
        first leg."""
        a, b = (float(a[0]), float(a[1])), (float(b[0]), float(b[1]))
        inside = [o for o in self.obstacles if o.contains(a)]
        if self.visible(a, b, inside):
            return [a, b]
        dist, prev = self._search(self._seen(a, inside))
        _, last = self._last(dist, self._seen(b))
        if last < 0:
            raise self._unreachable(a, b)
        out = [b]
        while last >= 0:
            out.append(self.nodes[last])
            last = prev[last]
        out.append(a)
        return out[::-1]

    def length(self, a: Point, b: Point) -> float:
        p = self.path(a, b)
        return sum(math.dist(p[k], p[k + 1]) for k in range(len(p) - 1))

    def unreachable(self, points: Sequence[Point]) -> tuple[int, int] | None:
        """A pair (0, k) of `points` with no drivable path between them (the first point cut off
        from points[0]), None when every point reaches
        every other: what `matrix` would refuse, without its searches. Union-find over the
        graph's edges, each point joined to the corners it sees and to the points it sees."""
        pts = [(float(p[0]), float(p[1])) for p in points]
        n = len(self.nodes)
        parent = list(range(n + len(pts)))

        def root(x: int) -> int:
            while parent[x] != x:
                parent[x] = parent[parent[x]]
                x = parent[x]
            return x

        def join(a: int, b: int) -> None:
            parent[root(a)] = root(b)

        def cut() -> int | None:
            return next((k for k in range(1, len(pts)) if root(n + k) != root(n)), None)

        for i, row in enumerate(self.edges):
            for j, _ in row:
                join(i, j)
        for k, p in enumerate(pts):  # first, the nearest corner each point sees: usually enough
            near = sorted(range(n), key=lambda i: math.dist(p, self.nodes[i]))
            i = next((i for i in near if self._tangent(i, p) and self.visible(p, self.nodes[i])),
                     None)
            if i is not None:
                join(n + k, i)
        if cut() is None:
            return None
        for k, p in enumerate(pts):  # else as `matrix` joins them: every corner seen, every leg
            for i, _ in self._seen(p):
                join(n + k, i)
        for k in range(len(pts)):
            for m in range(k):
                if root(n + m) != root(n + k) and self.visible(pts[m], pts[k]):
                    join(n + m, n + k)
        k = cut()
        return None if k is None else (0, k)

    def matrix(self, points: Sequence[Point]) -> tuple[tuple[float, ...], ...]:
        """Path lengths between every pair of `points`: one search per point, symmetric (each
        pair computed once), the same lengths as `length`."""
        pts = [(float(p[0]), float(p[1])) for p in points]
        seen = [self._seen(p) for p in pts]
        n = len(pts)
        out = [[0.0] * n for _ in range(n)]
        for i in range(n):
            dist = None
            for j in range(i + 1, n):
                if self.visible(pts[i], pts[j]):
                    d = math.dist(pts[i], pts[j])
                else:
                    if dist is None:
                        dist = self._search(seen[i])[0]
                    d, last = self._last(dist, seen[j])
                    if last < 0:
                        raise self._unreachable(pts[i], pts[j])
                out[i][j] = out[j][i] = d
        return tuple(tuple(row) for row in out)


def room_walls(width: float, height: float) -> list[Segment]:
    """The four walls of a `width` × `height` room centred on the origin."""
    w, h = width / 2, height / 2
    return [(-w, -h, w, -h), (w, -h, w, h), (w, h, -w, h), (-w, h, -w, -h)]


def point_segment_distance(p: Point, w: Segment) -> float:
    x1, y1, x2, y2 = w
    dx, dy = x2 - x1, y2 - y1
    norm = dx * dx + dy * dy
    t = 0.0 if norm == 0 else max(0.0, min(1.0, ((p[0] - x1) * dx + (p[1] - y1) * dy) / norm))
    return math.hypot(p[0] - x1 - t * dx, p[1] - y1 - t * dy)


def segment_distance(u: Segment, w: Segment) -> float:
    """The least distance between two segments (0 when they cross)."""
    a, b, c, d = (u[0], u[1]), (u[2], u[3]), (w[0], w[1]), (w[2], w[3])
    d1, d2 = _cross(*a, *b, *c), _cross(*a, *b, *d)
    d3, d4 = _cross(*c, *d, *a), _cross(*c, *d, *b)
    if d1 * d2 < 0 and d3 * d4 < 0:
        return 0.0
    return min(point_segment_distance(a, w), point_segment_distance(b, w),
               point_segment_distance(c, u), point_segment_distance(d, u))
