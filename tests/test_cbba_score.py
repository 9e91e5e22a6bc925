"""The discounted score CBBA bids (mrta_zenoh.planning.insertion) against its definition
restated in tests/harness/cbba_reference.py, and against schedule.route_visits' timing: marginal scores
at the best place (arrivals, waits, service times, rewards, distance matrices with and without
the triangle inequality), their least over a bundle's stages, and the sequential greedy
algorithm."""

from __future__ import annotations

import math
import random

import pytest

from mrta_zenoh.planning import Problem, Robot, Task, route_visits
from mrta_zenoh.planning.insertion import (DiscountedRoute, Origin, discounted_value,
                                           prefix_scores, ranks, sequential_greedy, starts)
from tests.harness.cbba_reference import LAMBDA, TIE, greedy, marginal, random_instance, score


def routed(rng: random.Random, twisted: bool = False) -> tuple[Problem, list[int], int]:
    """An instance, a route of some of its tasks for robot 0, and a task off the route;
    `twisted`: distances that break the triangle inequality (a detour can shorten a trip)."""
    p = random_instance(rng, 1, rng.randint(1, 8))
    if twisted:
        p = Problem.with_paths(p.robots, p.tasks,
                               lambda a, b: math.dist(a, b) * rng.choice((0.3, 1.0, 3.0)))
    order = list(range(len(p.tasks)))
    rng.shuffle(order)
    return p, order[1:], order[0]


@pytest.mark.parametrize("twisted", [False, True])
def test_the_marginal_score_is_the_best_increase_over_every_place(twisted):
    rng = random.Random(500 + twisted)
    for _ in range(300):
        p, route, j = routed(rng, twisted)
        if not p.capable(0, j):
            continue
        gain, place = DiscountedRoute(p, 0, route, LAMBDA).insertion(j)
        base = score(p, 0, route)
        gains = [score(p, 0, route[:n] + [j] + route[n:]) - base for n in range(len(route) + 1)]
        assert gain == pytest.approx(max(gains), abs=TIE)
        assert gains[place] == pytest.approx(max(gains), abs=TIE)
        assert all(g < max(gains) - TIE for g in gains[:place])  # the earliest of the best


def test_the_route_value_uses_schedule_timing_from_an_origin():
    rng = random.Random(502)
    for _ in range(100):
        p, route, _ = routed(rng)
        value = sum(LAMBDA ** v.start * p.tasks[v.task].reward for v in route_visits(p, 0, route))
        assert discounted_value(p, 0, route, LAMBDA) == pytest.approx(value)
        assert starts(p, 0, route) == pytest.approx([v.start for v in route_visits(p, 0, route)])
    # from an origin: after serving task 0 of a line at time 5, task 1 is 3 m on
    p = Problem((Robot("r", (0.0, 0.0), 1.0),), (Task("a", (1.0, 0.0)), Task("b", (4.0, 0.0))))
    assert starts(p, 0, [1], Origin(0, 5.0)) == [8.0]
    assert DiscountedRoute(p, 0, [], LAMBDA, Origin(0, 5.0)).insertion(1) == (LAMBDA ** 8, 0)


def test_of_equal_places_the_earliest_wins():
    # a stands where b does: before or after b, a is served at the same time and b is not
    # delayed — two places worth exactly the same
    p = Problem((Robot("r", (0.0, 0.0), 1.0),), (Task("a", (3.0, 4.0)), Task("b", (3.0, 4.0))))
    assert DiscountedRoute(p, 0, [1], LAMBDA).insertion(0) == (LAMBDA ** 5, 0)


def test_a_wait_absorbs_a_delay_and_ties_stay_exact():
    # b arrives at 100: inserting a before it (1 m out, 1 m back) changes nothing for b, so
    # a's marginal score is exactly λ^1, as it is on an empty route
    p = Problem((Robot("r", (0.0, 0.0), 1.0),),
                (Task("a", (0.0, 1.0)), Task("b", (0.0, 0.0), arrival=100.0)))
    assert DiscountedRoute(p, 0, [1], LAMBDA).insertion(0) == (LAMBDA ** 1, 0)
    assert DiscountedRoute(p, 0, [], LAMBDA).insertion(0) == (LAMBDA ** 1, 0)


def test_prefix_scores_are_the_least_marginal_over_the_bundle_stages():
    rng = random.Random(503)
    for _ in range(60):
        p = random_instance(rng, 1, rng.randint(2, 7))
        capable = [j for j in range(len(p.tasks)) if p.capable(0, j)]
        if len(capable) < 2:
            continue
        bundle = capable[:rng.randint(1, len(capable) - 1)]
        path = []
        for j in bundle:  # the route the bundle made, each task at its best place
            path.insert(marginal(p, 0, path, j)[1], j)
        levels = prefix_scores(p, 0, bundle, path, capable, LAMBDA)
        assert len(levels) == len(bundle) + 1
        for k, level in enumerate(levels):
            stage = [t for t in path if t in bundle[:k]]
            assert set(level) == set(capable) - set(bundle[:k])
            for j, (value, _) in level.items():
                least = min(marginal(p, 0, [t for t in path if t in bundle[:s]], j)[0]
                            for s in range(k + 1) if j not in bundle[:s])
                assert value == pytest.approx(least, abs=1e-12)
            raw = prefix_scores(p, 0, bundle, path, capable, LAMBDA, diminishing=False)[k]
            for j, (value, _) in raw.items():
                assert value == pytest.approx(marginal(p, 0, stage, j)[0], abs=1e-12)


@pytest.mark.parametrize("diminishing", [True, False])
def test_the_library_greedy_is_the_restated_one(diminishing):
    rng = random.Random(504 + diminishing)
    for _ in range(60):
        p = random_instance(rng, rng.randint(1, 4), rng.randint(1, 8))
        routes, picks = sequential_greedy(p, LAMBDA, diminishing=diminishing)
        expected_routes, expected_picks = greedy(p, diminishing=diminishing)
        assert routes == expected_routes
        assert [v for _, _, v in picks] == pytest.approx([v for _, _, v in expected_picks])
        total = sum(score(p, i, r) for i, r in routes.items())
        assert total == pytest.approx(sum(discounted_value(p, i, r, LAMBDA)
                                          for i, r in routes.items()))


def test_ranks_follow_string_order():
    assert ranks(["r2", "r10", "r1"]) == [2, 1, 0]
