"""Reference values (mrta_zenoh.planning.reference): the exact recursion equals a brute force
over every assignment and every order, written here from the objectives' definitions (not
through `schedule.evaluate`), for every objective; the routing search's best found is never
below the exact value and equals it on easy cases; every stated value is its routes' own value;
capabilities hold; the same problem gives the same routes."""

from __future__ import annotations

import itertools
import math
import random

import pytest

from mrta_zenoh.errors import ConfigError
from mrta_zenoh.planning import Problem, Robot, Task, evaluate
from mrta_zenoh.planning.reference import BEST_FOUND, EXACT, reference

OBJECTIVES = ("minsum", "makespan", "flowtime")


def random_problem(seed: int, robots: int, tasks: int, *, walls: bool = False) -> Problem:
    rng = random.Random(seed)
    rs = tuple(Robot(f"r{i}", (rng.uniform(-5, 5), rng.uniform(-4, 4)), rng.uniform(0.3, 0.9),
                     frozenset(c for c in ("lift", "cold") if i == 0 or rng.random() < 0.5))
               for i in range(robots))
    ts = tuple(Task(f"t{j}", (rng.uniform(-5, 5), rng.uniform(-4, 4)),
                    arrival=rng.choice([0.0, 0.0, round(rng.uniform(0, 25), 2)]),
                    service=round(rng.uniform(0, 6), 2),
                    capability=rng.choice(["", "", "lift", "cold"]))
               for j in range(tasks))
    if not walls:
        return Problem(rs, ts)
    # a detour factor that depends on the pair: distances no straight line gives
    return Problem.with_paths(rs, ts, lambda a, b: math.dist(a, b) * (1 + 0.3 * abs(
        math.sin(a[0] + b[1]))))


def brute_force(p: Problem, objective: str) -> float:
    """The best value over every map of tasks to capable robots and every order on each
    robot, timing each route by the definitions (docs/delivery.md, "Objectives")."""
    m, n = len(p.robots), len(p.tasks)
    best = math.inf
    for owner in itertools.product(range(m), repeat=n):
        if any(p.tasks[j].capability and p.tasks[j].capability not in p.robots[owner[j]]
               .capabilities for j in range(n)):
            continue
        per_robot = [[j for j in range(n) if owner[j] == i] for i in range(m)]
        totals = []
        for orders in itertools.product(*(itertools.permutations(s) for s in per_robot)):
            travel, ends = 0.0, []
            for i, order in enumerate(orders):
                t, here = 0.0, i
                for j in order:
                    leg = p.distance[here][m + j] / p.robots[i].speed
                    travel += leg
                    t = max(t + leg, p.tasks[j].arrival) + p.tasks[j].service
                    ends.append(t)
                    here = m + j
            totals.append(travel if objective == "minsum" else
                          max(ends, default=0.0) if objective == "makespan" else sum(ends))
        best = min(best, min(totals))
    return best


@pytest.mark.parametrize("objective", OBJECTIVES)
@pytest.mark.parametrize("seed", range(8))
def test_exact_equals_brute_force_on_tiny_instances(objective, seed):
    p = random_problem(seed, robots=2 + seed % 2, tasks=3 + seed % 3, walls=seed % 2 == 1)
    ref = reference(p, objective)
    assert ref.method == EXACT and ref.proven_optimal and ref.label == "optimal"
    assert ref.value == pytest.approx(brute_force(p, objective), abs=1e-9)
    assert evaluate(p, ref.routes).value(objective) == pytest.approx(ref.value, abs=1e-12)
    assert sorted(j for r in ref.routes.values() for j in r) == list(range(len(p.tasks)))


@pytest.mark.parametrize("objective", OBJECTIVES)
def test_three_robots_seven_tasks_exactly(objective):
    p = random_problem(42, robots=3, tasks=7)
    ref = reference(p, objective)
    assert ref.proven_optimal
    # a spot check against the brute force, which enumerates 3⁷ maps and their orders
    assert ref.value == pytest.approx(brute_force(p, objective), abs=1e-9)
    for i, route in ref.routes.items():
        for j in route:
            need = p.tasks[j].capability
            assert not need or need in p.robots[i].capabilities


@pytest.mark.parametrize("objective", OBJECTIVES)
@pytest.mark.parametrize("seed", range(3))
def test_best_found_is_never_below_the_exact_value_and_states_its_routes_value(objective, seed):
    p = random_problem(100 + seed, robots=3, tasks=6)
    exact = reference(p, objective)
    found = reference(p, objective, exact_limit=0, solutions=300)
    assert found.method == BEST_FOUND and not found.proven_optimal
    assert found.label == "best found"
    assert found.value >= exact.value - 1e-9
    assert evaluate(p, found.routes).value(objective) == pytest.approx(found.value, abs=1e-12)
    for i, route in found.routes.items():
        for j in route:
            assert p.capable(i, j)
    assert sorted(j for r in found.routes.values() for j in r) == list(range(6))


@pytest.mark.parametrize("objective", OBJECTIVES)
def test_best_found_equals_the_exact_value_on_an_easy_case(objective):
    # two robots, each with two tasks in a line beyond it and nothing close to the other:
    # every objective is best served by each robot taking its own line, nearest first
    p = Problem((Robot("a", (0.0, 0.0), 1.0), Robot("b", (0.0, 10.0), 0.5)),
                (Task("a1", (1.0, 0.0), service=1.0), Task("a2", (2.0, 0.0), arrival=3.0),
                 Task("b1", (1.0, 10.0)), Task("b2", (2.0, 10.0), service=2.0)))
    found = reference(p, objective, exact_limit=0, solutions=200)
    assert found.routes == {0: [0, 1], 1: [2, 3]}
    assert found.value == pytest.approx(reference(p, objective).value)


@pytest.mark.slow
def test_the_routing_search_is_deterministic_and_keeps_capabilities():
    p = random_problem(7, robots=4, tasks=14)
    a = reference(p, "flowtime", solutions=300)
    b = reference(p, "flowtime", solutions=300)
    assert a.method == BEST_FOUND and a.routes == b.routes and a.value == b.value
    for i, route in a.routes.items():
        for j in route:
            assert p.capable(i, j), (p.robots[i].id, p.tasks[j].id)


def wall_limits(message, prefix=""):
    """Every wall-time limit (a protobuf Duration) among a search's parameters, by path."""
    out = {}
    for field in message.DESCRIPTOR.fields:
        if field.message_type is None or field.is_repeated:
            continue
        value = getattr(message, field.name)
        if field.message_type.full_name == "google.protobuf.Duration":
            out[prefix + field.name] = value.ToMicroseconds() / 1e6
        else:
            out.update(wall_limits(value, f"{prefix}{field.name}."))
    return out


def test_no_wall_limit_inside_the_routing_search_is_shorter_than_its_cap():
    """A reference is a function of the instance, not of the machine's speed: the search ends
    on its solution count; the one wall limit is the cap (reported when reached) — OR-Tools'
    default cuts each large-neighbourhood sub-search at 100 ms of wall, which a busy machine
    reaches sooner, sending the search another way (issue 50)."""
    from mrta_zenoh.planning.routing import search_parameters
    params = search_parameters(200, 30.0)
    assert wall_limits(params) == {"time_limit": 30.0, "lns_time_limit": 30.0}
    assert params.solution_limit == 200
    assert params.sat_parameters.max_time_in_seconds == math.inf


def test_unservable_tasks_and_unknown_objectives_are_errors():
    p = Problem((Robot("r", (0.0, 0.0), 1.0),), (Task("t", (1.0, 0.0), capability="fly"),))
    with pytest.raises(ConfigError, match="no robot has capability 'fly'"):
        reference(p, "minsum")
    with pytest.raises(ConfigError, match="no robot has capability 'fly'"):
        reference(p, "minsum", exact_limit=0)
    with pytest.raises(ConfigError, match="unknown objective 'span'"):
        reference(p, "span")


def test_no_tasks_is_worth_nothing():
    p = Problem((Robot("r", (0.0, 0.0), 1.0),), ())
    for objective in OBJECTIVES:
        assert reference(p, objective).value == 0.0
        assert reference(p, objective, exact_limit=-1).value == 0.0


def test_flowtime_keeps_earlier_but_costlier_prefixes():
    # one robot, five tasks with arrivals: the best order starts with a prefix that sums more
    # than another order of the same tasks but ends earlier (keeping one label per state, the
    # least sum so far, misses the optimum by ≈ 6 s: found by that mutation)
    p = random_problem(30, robots=1, tasks=5)
    assert reference(p, "flowtime").value == pytest.approx(brute_force(p, "flowtime"), abs=1e-9)
