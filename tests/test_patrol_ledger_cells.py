"""The patrol ledger's border cells (issue #27): a position is compared with the cells of the
grid buckets around it, not with every cell — and must visit exactly the cells the loop over
every cell visits, wherever the robot and whatever the border (fixed seed)."""

import math

import pytest
from hypothesis import given, settings, strategies as st

from mrta_patrol.ledger import CellGrid, PatrolLedger, rectangle_cells

coord = st.floats(-60.0, 60.0, allow_nan=False)


def every_cell(cells, mask, x, y, reach):
    for i, (cx, cy) in enumerate(cells):
        if math.hypot(cx - x, cy - y) <= reach:
            mask |= 1 << i
    return mask


@pytest.mark.slow
@settings(max_examples=300, derandomize=True, deadline=None)
@given(coord, coord, st.floats(0.5, 40.0), st.floats(0.5, 30.0),
       st.lists(st.tuples(coord, coord), min_size=1, max_size=20), st.integers(0, 2**64))
def test_the_grid_visits_the_cells_the_loop_over_every_cell_visits(x0, y0, w, h, path, start):
    cells = rectangle_cells(x0, y0, x0 + w, y0 + h, PatrolLedger.CELL)
    grid = CellGrid(cells, PatrolLedger.REACH)
    start &= (1 << len(cells)) - 1
    fast = slow = start
    for x, y in path + [(cx + 1.99, cy) for cx, cy in cells[::7]]:
        fast = grid.visit(fast, x, y)
        slow = every_cell(cells, slow, x, y, PatrolLedger.REACH)
        assert fast == slow


def test_a_cell_exactly_at_reach_is_visited():
    cells = [(0.0, 0.0), (4.0, 0.0)]
    grid = CellGrid(cells, 2.0)
    assert grid.visit(0, 2.0, 0.0) == 0b11
    assert grid.visit(0, -2.0, 0.0) == 0b01
