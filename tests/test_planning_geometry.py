"""Shortest drivable paths around walls (mrta_zenoh.planning.geometry), against independent
computations: a fine-grid Dijkstra over the free space (scipy's csgraph on a 16-connected
grid, cells free when farther than the clearance from every wall), the tangent-and-arc length
around one wall by hand, and the path's own clearance measured by segment distances written
here; plus straight lines where nothing blocks, symmetry and the triangle inequality."""

from __future__ import annotations

import math
import random

import numpy as np
import pytest
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import dijkstra

from mrta_zenoh.errors import ConfigError
from mrta_zenoh.planning.geometry import CLEARANCE, PathMap, room_walls

R = CLEARANCE


def seg_point(w, p) -> float:
    x1, y1, x2, y2 = w
    dx, dy = x2 - x1, y2 - y1
    t = max(0.0, min(1.0, ((p[0] - x1) * dx + (p[1] - y1) * dy) / (dx * dx + dy * dy)))
    return math.hypot(p[0] - x1 - t * dx, p[1] - y1 - t * dy)


def seg_seg(w, a, b) -> float:
    """Distance between wall w and segment a–b (0 when they cross), sampled finely along a–b
    and exactly at the wall's ends."""
    n = max(2, int(math.dist(a, b) / 0.005))
    along = min(seg_point(w, (a[0] + (b[0] - a[0]) * k / n, a[1] + (b[1] - a[1]) * k / n))
                for k in range(n + 1))
    ends = min(seg_point((a[0], a[1], b[0], b[1]), (w[0], w[1])),
               seg_point((a[0], a[1], b[0], b[1]), (w[2], w[3])))
    return min(along, ends)


def grid_length(walls, a, b, width=12.0, height=8.0, h=0.05) -> float:
    xs = np.arange(-width / 2, width / 2 + h / 2, h)
    ys = np.arange(-height / 2, height / 2 + h / 2, h)
    gx, gy = np.meshgrid(xs, ys, indexing="ij")

    def clear(px, py):
        d = np.full(px.shape, np.inf)
        for x1, y1, x2, y2 in walls:
            dx, dy = x2 - x1, y2 - y1
            t = np.clip(((px - x1) * dx + (py - y1) * dy) / (dx * dx + dy * dy), 0, 1)
            d = np.minimum(d, np.hypot(px - x1 - t * dx, py - y1 - t * dy))
        return d >= R

    free = clear(gx, gy)
    nx, ny = free.shape
    idx = np.arange(nx * ny).reshape(nx, ny)
    moves = [(1, 0), (0, 1), (1, 1), (1, -1), (2, 1), (1, 2), (2, -1), (1, -2)]
    rows, cols, lens = [], [], []
    for dx, dy in moves:
        i0, i1 = max(0, -dx), nx - max(0, dx)
        j0, j1 = max(0, -dy), ny - max(0, dy)
        a_ok = free[i0:i1, j0:j1] & free[i0 + dx:i1 + dx, j0 + dy:j1 + dy]
        mid = clear(gx[i0:i1, j0:j1] + dx * h / 2, gy[i0:i1, j0:j1] + dy * h / 2)
        ok = a_ok & mid
        rows.append(idx[i0:i1, j0:j1][ok])
        cols.append(idx[i0 + dx:i1 + dx, j0 + dy:j1 + dy][ok])
        lens.append(np.full(ok.sum(), h * math.hypot(dx, dy)))
    g = coo_matrix((np.concatenate(lens), (np.concatenate(rows), np.concatenate(cols))),
                   shape=(nx * ny, nx * ny)).tocsr()

    def cell(p):
        return idx[int(round((p[0] + width / 2) / h)), int(round((p[1] + height / 2) / h))]

    return float(dijkstra(g, directed=False, indices=cell(a))[cell(b)])


def random_walls(seed: int) -> list:
    rng = random.Random(seed)
    walls = room_walls(12.0, 8.0)
    for _ in range(3):
        x, y = rng.uniform(-4, 4), rng.uniform(-2.5, 2.5)
        ang, length = rng.uniform(0, math.pi), rng.uniform(1.5, 4)
        walls.append((x, y, x + length * math.cos(ang), y + length * math.sin(ang)))
    return walls


def free_point(rng, walls):
    while True:
        p = (rng.uniform(-5.5, 5.5), rng.uniform(-3.5, 3.5))
        if min(seg_point(w, p) for w in walls) > R + 0.1:
            return p


def test_around_one_wall_the_path_is_the_tangents_and_arc_plus_at_most_the_polygon_excess():
    m = PathMap([(0.0, -1.0, 0.0, 1.0)])
    a, b = (-2.0, 0.0), (2.0, 0.0)
    # by hand: tangent from a to the disc of radius R at the wall's end (0, ±1), the arc over
    # the end, the tangent down to b
    d = math.sqrt(5.0)
    arc = (2 * math.pi - 2 * math.atan(2.0)) - 2 * math.acos(R / d)
    capsule = 2 * math.sqrt(d * d - R * R) + R * arc
    length = m.length(a, b)
    assert capsule - 1e-9 <= length <= capsule * 1.02
    assert m.length(a, b) == pytest.approx(m.length(b, a))


def test_nothing_in_the_way_is_a_straight_line():
    m = PathMap(room_walls(12.0, 8.0) + [(0.0, 1.0, 0.0, 4.0)])
    assert m.path((-3.0, -1.0), (3.0, -2.0)) == [(-3.0, -1.0), (3.0, -2.0)]
    assert m.length((-3.0, -1.0), (3.0, -2.0)) == pytest.approx(math.dist((-3, -1), (3, -2)))


@pytest.mark.parametrize("seed", range(4))
def test_lengths_match_a_fine_grid_search_and_paths_keep_their_clearance(seed):
    walls = random_walls(seed)
    m = PathMap(walls)
    rng = random.Random(1000 + seed)
    for _ in range(3):
        a, b = free_point(rng, walls), free_point(rng, walls)
        path = m.path(a, b)
        length = sum(math.dist(path[k], path[k + 1]) for k in range(len(path) - 1))
        grid = grid_length(walls, a, b)
        # the grid walks 16 headings (≤ 2.75 % longer than a straight leg) and snaps both
        # ends to its cells (≤ 3.6 cm each); the polygons add a few cm per corner
        assert grid / 1.0275 - 0.08 <= length <= grid + 0.08, (a, b, path, grid)
        for k in range(len(path) - 1):
            for w in walls:
                assert seg_seg(w, path[k], path[k + 1]) >= R - 1e-3, (w, path[k], path[k + 1])


@pytest.mark.parametrize("seed", range(3))
def test_the_matrix_is_symmetric_and_obeys_the_triangle_inequality(seed):
    walls = random_walls(seed)
    rng = random.Random(seed)
    points = [free_point(rng, walls) for _ in range(8)]
    d = PathMap(walls).matrix(points)
    for i in range(8):
        assert d[i][i] == 0.0
        for j in range(8):
            assert d[i][j] == d[j][i]
            assert d[i][j] >= math.dist(points[i], points[j]) - 1e-9
            for k in range(8):
                assert d[i][j] <= d[i][k] + d[k][j] + 1e-9


def test_points_too_close_to_a_wall_and_closed_off_points_are_errors():
    m = PathMap(room_walls(12.0, 8.0) + [(-1.0, -4.0, -1.0, 4.0)])
    with pytest.raises(ConfigError, match=r"task t1 at \(-0.9, 0\) is closer than 0.4 m"):
        m.check_point((-0.9, 0.0), "task t1")
    m.check_point((-2.0, 0.0), "task t1")
    with pytest.raises(ConfigError, match="no drivable path"):
        m.path((-3.0, 0.0), (3.0, 0.0))


@pytest.mark.multiprocess
def test_what_agents_import_loads_no_numpy_scipy_or_ortools():
    import subprocess
    import sys
    code = ("import sys, mrta_zenoh.planning, mrta_zenoh.planning.geometry, mrta_delivery.layers,"
            " mrta_delivery.evaluators; print(sorted(m for m in ('numpy', 'scipy', 'ortools')"
            " if m in sys.modules))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         timeout=120)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == "[]"


def full_graph_lengths(m: PathMap, points) -> list[list[float]]:
    """Shortest paths over the *full* visibility graph (every corner pair that sees each other,
    every point to every corner it sees: no tangent pruning), by scipy's Dijkstra."""
    nodes = list(m.nodes) + [tuple(p) for p in points]
    n = len(nodes)
    rows, cols, lens = [], [], []
    for i in range(n):
        for j in range(i + 1, n):
            if m.visible(nodes[i], nodes[j]):
                rows.append(i)
                cols.append(j)
                lens.append(math.dist(nodes[i], nodes[j]))
    g = coo_matrix((lens, (rows, cols)), shape=(n, n)).tocsr()
    d = dijkstra(g, directed=False, indices=list(range(len(m.nodes), n)))
    return [[float(d[a][len(m.nodes) + b]) for b in range(len(points))]
            for a in range(len(points))]


@pytest.mark.parametrize("seed", range(6))
def test_the_tangent_graph_gives_the_lengths_of_the_full_visibility_graph(seed):
    """PathMap keeps only bitangent edges (issue 51.5: the graph's cost); on crowded maps with
    overlapping, crossing and touching walls its lengths are the full graph's."""
    rng = random.Random(seed)
    walls = room_walls(12.0, 8.0)
    for _ in range(8):
        x, y = rng.uniform(-5, 5), rng.uniform(-3, 3)
        ang, length = rng.choice([0.0, math.pi / 2, rng.uniform(0, math.pi)]), rng.uniform(0.5, 3)
        walls.append((x, y, x + length * math.cos(ang), y + length * math.sin(ang)))
    m = PathMap(walls)
    points = [free_point(rng, walls) for _ in range(7)]
    full = full_graph_lengths(m, points)
    try:
        got = m.matrix(points)
    except ConfigError:  # some pair closed off: the full graph and `unreachable` say so too
        assert any(math.isinf(x) for row in full for x in row)
        assert m.unreachable(points) is not None
        return
    assert m.unreachable(points) is None
    for i in range(len(points)):
        for j in range(len(points)):
            assert got[i][j] == pytest.approx(full[i][j], abs=1e-9), (i, j)


def test_unreachable_names_a_point_walled_in_and_nothing_when_all_connect():
    box = [(2.0, 1.0, 4.0, 1.0), (4.0, 1.0, 4.0, 3.0), (4.0, 3.0, 2.0, 3.0), (2.0, 3.0, 2.0, 1.0)]
    m = PathMap(room_walls(12.0, 8.0) + box)
    inside, a, b = (3.0, 2.0), (-3.0, 0.0), (0.0, -2.0)
    assert m.unreachable([a, b, inside]) == (0, 2)
    assert m.unreachable([inside, a]) == (0, 1)
    assert m.unreachable([a, b, (5.0, 2.0)]) is None
    with pytest.raises(ConfigError, match="no drivable path"):
        m.matrix([a, b, inside])
