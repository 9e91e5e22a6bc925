"""benchmarks/solomon.py: a Solomon-format file read by vrplib, its first N customers kept, the
solver's routes checked in floats (every customer once, capacity, windows, back by the depot's
due) and equal to a brute force on a tiny instance under the exact methods' convention
(least distance, distances truncated to one decimal)."""

from __future__ import annotations

import itertools
import math

import pytest

from benchmarks.solomon import check, distances, read, read_best_known, solve_pyvrp

TINY = """TINY1

VEHICLE
NUMBER     CAPACITY
  3         30

CUSTOMER
CUST NO.  XCOORD.   YCOORD.    DEMAND   READY TIME  DUE DATE   SERVICE   TIME

    0     10     10      0      0    200      0
    1     13     14     10     10     40      5
    2     20     10     15      0    100      5
    3     10     23     10     50     80      5
    4      4      6     10      0     30      5
    5     17     17     10     60     90      5
"""


def brute_force(inst, dist) -> float:
    """Least total distance over every split of the customers into ordered routes."""
    n, best = inst["customers"], math.inf
    for perm in itertools.permutations(range(1, n + 1)):
        for cuts in itertools.product((False, True), repeat=n - 1):
            routes, cur = [], [perm[0]]
            for c, cut in zip(perm[1:], cuts):
                if cut:
                    routes.append(cur)
                    cur = []
                cur.append(c)
            routes.append(cur)
            if len(routes) > inst["vehicles"]:
                continue
            try:
                best = min(best, check(inst, dist, routes))
            except ValueError:
                pass
    return best


def test_tiny_instance_solved_to_the_brute_force_optimum(tmp_path):
    path = tmp_path / "TINY1.txt"
    path.write_text(TINY)
    inst = read(path, None)
    assert inst["customers"] == 5 and inst["capacity"] == 30
    dist = distances(inst, truncated=True)
    assert dist[0][1] == 5.0 and dist[0][5] == 9.8  # √98 = 9.899… truncated to one decimal
    routes = solve_pyvrp(inst, dist, vehicles_first=False, seconds=1.0)
    assert check(inst, dist, routes) == pytest.approx(brute_force(inst, dist), abs=1e-9)
    assert read(path, 3)["customers"] == 3  # the first customers, as Solomon's 25 are made


def test_check_refuses_a_late_start_and_an_overload(tmp_path):
    path = tmp_path / "TINY1.txt"
    path.write_text(TINY)
    inst = read(path, None)
    dist = distances(inst, truncated=False)
    with pytest.raises(ValueError, match="after its due"):
        check(inst, dist, [[3, 4], [1, 2, 5]])  # customer 4 due at 30, reached after 3's 50
    with pytest.raises(ValueError, match="capacity"):
        check(inst, dist, [[4, 1, 2], [3, 5]])  # 35 > 30
    with pytest.raises(ValueError, match="exactly once"):
        check(inst, dist, [[4, 1, 2]])


def test_every_solomon_instance_has_both_best_known_values():
    best = read_best_known()
    names = {name for name, _ in best}
    assert len(names) == 56
    assert all((name, 25) in best and (name, 100) in best for name in names)
    assert best[("R101", 100)]["vehicles"] == "19" and best[("C101", 25)]["distance"] == "191.3"
