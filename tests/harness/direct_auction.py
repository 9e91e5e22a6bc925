"""Sequential single-item auctions restated from their definition, for SSI's and TeSSI's tests:
each round every (robot, open task, place in the robot's route) is priced, and the least price —
ties: lower robot id, lower task id, earlier place — wins that task, inserted there. The rule
is the `price(route, new_route, robot)` given: the MinSum rule's added travel (SSI), or a
temporal network's makespan where it stays consistent (TeSSI: None elsewhere)."""

from __future__ import annotations

from typing import Callable

from mrta_zenoh.planning import Problem

Price = Callable[[list[int], list[int], int], "float | None"]


def direct_auction(p: Problem, price: Price, tasks=None, routes=None, robots=None):
    """The routes (robot index → task indices) and the awards in order (task, robot, price)."""
    robots = range(len(p.robots)) if robots is None else robots
    routes = {i: list((routes or {}).get(i, [])) for i in robots}
    left = set(range(len(p.tasks)) if tasks is None else tasks)
    awards = []
    while left:
        best = None
        for i in robots:
            for j in left:
                if not p.capable(i, j):
                    continue
                r = routes[i]
                for pos in range(len(r) + 1):
                    cost = price(r, r[:pos] + [j] + r[pos:], i)
                    if cost is None:
                        continue
                    key = (cost, p.robots[i].id, p.tasks[j].id, pos, i, j)
                    if best is None or key < best:
                        best = key
        if best is None:
            break
        cost, _, _, pos, i, j = best
        routes[i].insert(pos, j)
        left.discard(j)
        awards.append((j, i, cost))
    return routes, awards
