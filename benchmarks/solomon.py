"""A check of the reference solver against published values: Solomon's VRPTW benchmark (Solomon,
"Algorithms for the vehicle routing and scheduling problems with time window constraints",
Operations Research 35(2), 1987) solved on Solomon's own objective, each instance's gap to its
best-known value.

    python benchmarks/solomon.py DIR [--customers 25] [--solver pyvrp|ortools] [--seconds S]

DIR holds Solomon-format files (C101.txt …, read by `vrplib`); `--customers N` keeps the depot
and the first N customers, which is how Solomon's 25- and 50-customer instances are made from
the 100-customer files. One JSON line per instance, then one per summary figure.

Solomon's objective, not the robots' (no open routes here): identical vehicles of the file's
capacity leave the depot within its window, serve each customer's demand starting inside its
window [ready, due] (waiting allowed), and return to the depot by its due. The published values
follow two conventions, and each row of `solomon_best_known.csv` says which it is:

* `distance` (exact methods; Solomon's 25- and 50-customer optima): least total distance, the
  number of vehicles free, distances and times truncated to one decimal;
* `vehicles,distance` (heuristics; the 100-customer best known): fewest vehicles, then least
  distance, in double precision (rounded to two decimals when reported).

The solver: PyVRP's hybrid genetic search (the engine of mrta_zenoh.planning.pyvrp_routing),
or OR-Tools' guided local search (routing.py's engine) for comparison; a vehicle's fixed cost
larger than any routes' distance makes vehicles count first. Stopped after `--seconds` (wall
time: a search cut by time depends on the machine; the gaps are what this machine found).
A gap is 100 · (distance / best-known − 1), reported also when more vehicles were used (then
`vehicles_over` > 0, the row does not reach the best known and the summary's gaps leave it out:
more vehicles usually buy less distance).
"""

from __future__ import annotations

import argparse
import csv
import json
import math
import statistics
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

BEST_KNOWN = Path(__file__).resolve().parent / "solomon_best_known.csv"


def read_best_known(path: Path = BEST_KNOWN) -> dict[tuple[str, int], dict]:
    with open(path, newline="") as f:
        rows = [r for r in csv.DictReader(line for line in f if not line.startswith("#"))]
    return {(r["instance"].upper(), int(r["customers"])): r for r in rows}


def read(path: Path, customers: int | None) -> dict:
    import vrplib

    d = vrplib.read_instance(str(path), instance_format="solomon")
    n = len(d["demand"]) - 1 if customers is None else customers
    keep = slice(0, n + 1)
    return {"name": path.stem.upper(), "customers": n, "vehicles": int(d["vehicles"]),
            "capacity": int(d["capacity"]),
            "xy": [tuple(map(float, p)) for p in d["node_coord"][keep]],
            "demand": [int(q) for q in d["demand"][keep]],
            "window": [tuple(map(float, w)) for w in d["time_window"][keep]],
            "service": [float(s) for s in d["service_time"][keep]]}


def distances(inst: dict, truncated: bool) -> list[list[float]]:
    """Euclidean distances, truncated to one decimal under the exact methods' convention."""
    xy = inst["xy"]
    out = [[math.dist(a, b) for b in xy] for a in xy]
    if truncated:
        out = [[math.floor(10 * d) / 10 for d in row] for row in out]
    return out


SCALE = 1000  # solver units per distance/time unit (integers)


def solve_pyvrp(inst: dict, dist: list[list[float]], vehicles_first: bool,
                seconds: float, seed: int = 0) -> list[list[int]]:
    from pyvrp import Model
    from pyvrp.stop import MaxRuntime

    n = inst["customers"]
    m = Model()
    locs = [m.add_location(*p) for p in inst["xy"]]
    e0, l0 = inst["window"][0]
    depot = m.add_depot(locs[0], tw_early=round(e0 * SCALE), tw_late=round(l0 * SCALE))
    fixed = (round(sum(max(r) for r in dist) * SCALE) + 1) if vehicles_first else 0
    m.add_vehicle_type(inst["vehicles"], capacity=[inst["capacity"]], start_depot=depot,
                       end_depot=depot, fixed_cost=fixed, tw_early=round(e0 * SCALE),
                       tw_late=round(l0 * SCALE))
    for k in range(1, n + 1):
        e, l = inst["window"][k]
        m.add_client(locs[k], delivery=[inst["demand"][k]],
                     service_duration=round(inst["service"][k] * SCALE),
                     tw_early=round(e * SCALE), tw_late=round(l * SCALE))
    for a in range(n + 1):
        for b in range(n + 1):
            if a != b:
                d = round(dist[a][b] * SCALE)
                m.add_edge(locs[a], locs[b], d, d)
    result = m.solve(MaxRuntime(seconds), seed=seed, display=False)
    return [[a.idx + 1 for a in r if a.is_client()] for r in result.best.routes()]  # clients 0…


def solve_ortools(inst: dict, dist: list[list[float]], vehicles_first: bool,
                  seconds: float) -> list[list[int]]:
    from ortools.constraint_solver import pywrapcp, routing_enums_pb2

    n, k = inst["customers"], inst["vehicles"]
    manager = pywrapcp.RoutingIndexManager(n + 1, k, 0)
    routing = pywrapcp.RoutingModel(manager)
    d = [[round(x * SCALE) for x in row] for row in dist]
    svc = [round(s * SCALE) for s in inst["service"]]
    arc = routing.RegisterTransitMatrix(d)
    routing.SetArcCostEvaluatorOfAllVehicles(arc)
    if vehicles_first:
        routing.SetFixedCostOfAllVehicles(round(sum(max(r) for r in dist) * SCALE) + 1)
    clock_cb = routing.RegisterTransitMatrix([[d[a][b] + svc[a] for b in range(n + 1)]
                                              for a in range(n + 1)])
    horizon = round(inst["window"][0][1] * SCALE)
    routing.AddDimension(clock_cb, horizon, horizon, False, "time")
    clock = routing.GetDimensionOrDie("time")
    for node in range(1, n + 1):
        e, l = inst["window"][node]
        clock.CumulVar(manager.NodeToIndex(node)).SetRange(round(e * SCALE), round(l * SCALE))
    load = routing.RegisterUnaryTransitVector(inst["demand"])
    routing.AddDimensionWithVehicleCapacity(load, 0, [inst["capacity"]] * k, True, "load")
    params = pywrapcp.DefaultRoutingSearchParameters()
    params.first_solution_strategy = (
        routing_enums_pb2.FirstSolutionStrategy.PARALLEL_CHEAPEST_INSERTION)
    params.local_search_metaheuristic = (
        routing_enums_pb2.LocalSearchMetaheuristic.GUIDED_LOCAL_SEARCH)
    params.time_limit.FromMilliseconds(round(seconds * 1000))
    solution = routing.SolveWithParameters(params)
    if solution is None:
        return []
    routes = []
    for v in range(k):
        index, route = routing.Start(v), []
        index = solution.Value(routing.NextVar(index))
        while not routing.IsEnd(index):
            route.append(manager.IndexToNode(index))
            index = solution.Value(routing.NextVar(index))
        if route:
            routes.append(route)
    return routes


def check(inst: dict, dist: list[list[float]], routes: list[list[int]]) -> float:
    """The routes' total distance, after checking them in floats: every customer once,
    capacity, every start in its window, back at the depot by its due (ValueError if not)."""
    seen = sorted(c for r in routes for c in r)
    if seen != list(range(1, inst["customers"] + 1)):
        raise ValueError("not every customer served exactly once")
    total = 0.0
    for r in routes:
        if sum(inst["demand"][c] for c in r) > inst["capacity"]:
            raise ValueError("capacity exceeded")
        t, at = inst["window"][0][0], 0
        for c in r + [0]:
            t += dist[at][c]
            total += dist[at][c]
            e, l = inst["window"][c]
            if t > l + 1e-6:
                raise ValueError(f"customer {c} reached at {t:.3f}, after its due {l}")
            t = max(t, e) + (inst["service"][c] if c else 0.0)
            at = c
    return total


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("dir", type=Path, help="a folder of Solomon-format files")
    ap.add_argument("--customers", type=int, default=None,
                    help="keep the first N customers (25 or 50: Solomon's smaller sets)")
    ap.add_argument("--solver", choices=("pyvrp", "ortools"), default="pyvrp")
    ap.add_argument("--seconds", type=float, default=5.0, help="search time per instance")
    ap.add_argument("--only", default="", help="comma-separated instance names")
    args = ap.parse_args()
    best = read_best_known()
    gaps, reached, over, secs = [], 0, 0, []  # gaps: rows with no more vehicles than best
    only = {s.upper() for s in args.only.split(",") if s}
    for path in sorted(p for p in args.dir.iterdir() if p.is_file()):
        if only and path.stem.upper() not in only:
            continue
        inst = read(path, args.customers)
        row = best.get((inst["name"], inst["customers"]))
        if row is None:
            continue
        vehicles_first = row["objective"] == "vehicles,distance"
        dist = distances(inst, truncated=not vehicles_first)
        t0 = time.perf_counter()
        routes = (solve_pyvrp(inst, dist, vehicles_first, args.seconds) if args.solver == "pyvrp"
                  else solve_ortools(inst, dist, vehicles_first, args.seconds))
        seconds = time.perf_counter() - t0
        value = check(inst, dist, routes)
        bk_distance, bk_vehicles = float(row["distance"]), int(row["vehicles"])
        gap = 100.0 * (value / bk_distance - 1)
        more = len(routes) - bk_vehicles if vehicles_first else 0
        if more <= 0:
            gaps.append(gap)
        secs.append(seconds)
        over += more > 0
        reached += more <= 0 and gap <= 0.005
        print(json.dumps({"figure": "solomon gap", "instance": inst["name"],
                          "customers": inst["customers"], "objective": row["objective"],
                          "solver": args.solver, "seconds_limit": args.seconds,
                          "vehicles": len(routes), "distance": round(value, 2),
                          "best_known_vehicles": bk_vehicles, "best_known_distance": bk_distance,
                          "vehicles_over": more, "gap_pct": round(gap, 3) + 0.0,  # not -0.0
                          "seconds": round(seconds, 2)}), flush=True)
    if secs:  # distance gaps over the instances solved with no more vehicles than the best
        print(json.dumps({"figure": "solomon summary", "customers": args.customers or 100,
                          "solver": args.solver, "seconds_limit": args.seconds,
                          "instances": len(secs), "at_best_known": reached,
                          "more_vehicles": over,
                          "mean_gap_pct": round(statistics.fmean(gaps), 3) if gaps else None,
                          "max_gap_pct": round(max(gaps), 3) if gaps else None,
                          "within_1pct": sum(g <= 1.0 for g in gaps),
                          "median_s": round(statistics.median(secs), 2)}), flush=True)


if __name__ == "__main__":
    main()
