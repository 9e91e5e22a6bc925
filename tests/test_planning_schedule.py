"""Route timing and the three objectives (mrta_zenoh.planning), against hand computations and a
direct re-statement of the definitions in docs/delivery.md."""

from __future__ import annotations

import math

import pytest
from hypothesis import given, settings, strategies as st

from mrta_zenoh.errors import ConfigError
from mrta_zenoh.planning import Problem, Robot, Task, evaluate, route_visits, routes_by_id


def two_robots() -> Problem:
    return Problem((Robot("r1", (0.0, 0.0), 0.5, frozenset({"lift"})),
                    Robot("r2", (3.0, 0.0), 1.0)),
                   (Task("a", (3.0, 4.0), capability="lift", service=2.0),
                    Task("b", (0.0, 4.0), arrival=20.0, service=1.0),
                    Task("c", (3.0, 0.0))))


def test_a_route_waits_for_a_late_task_and_adds_service_times():
    p = two_robots()
    v = route_visits(p, 0, [0, 1])
    # r1 at 0.5 m/s: 5 m to a (10 s), serve 2 s, 3 m to b (6 s) → reach 18, wait until 20
    assert [(x.travel, x.reach, x.start, x.end) for x in v] == [
        (pytest.approx(10.0), pytest.approx(10.0), pytest.approx(10.0), pytest.approx(12.0)),
        (pytest.approx(6.0), pytest.approx(18.0), pytest.approx(20.0), pytest.approx(21.0))]


def test_objectives_are_sums_and_maxima_of_the_timing():
    p = two_robots()
    e = evaluate(p, {0: [0, 1], 1: [2]})
    assert e.total_travel == pytest.approx(10.0 + 6.0 + 0.0)
    assert e.makespan == pytest.approx(21.0)
    assert e.flowtime == pytest.approx(12.0 + 21.0 + 0.0)
    assert e.served == 3
    assert e.value("minsum") == e.total_travel and e.value("makespan") == e.makespan


def test_routes_that_break_the_rules_are_refused():
    p = two_robots()
    with pytest.raises(ConfigError, match="cannot serve task a"):
        evaluate(p, {1: [0]})
    with pytest.raises(ConfigError, match="on the routes of r1 and r2"):
        evaluate(p, {0: [1], 1: [1]})
    with pytest.raises(ConfigError, match="appears twice"):
        Problem((Robot("r", (0, 0), 1.0), Robot("r", (1, 0), 1.0)), ())
    with pytest.raises(ConfigError, match="speed"):
        Problem((Robot("r", (0, 0), 0.0),), ())
    with pytest.raises(ConfigError, match="arrival"):
        Problem((), (Task("t", (0, 0), arrival=-1.0),))


def test_ids_and_restriction_keep_distances():
    p = two_robots()
    assert routes_by_id(p, {"r2": ["c", "b"]}) == {1: [2, 1]}
    q = p.restricted(["c", "a"])
    assert [t.id for t in q.tasks] == ["c", "a"]
    assert q.travel(0, None, 1) == pytest.approx(p.travel(0, None, 0))
    assert q.travel(1, 0, 1) == pytest.approx(p.travel(1, 2, 0))


def test_given_distances_are_used_instead_of_straight_lines():
    robots = (Robot("r", (0.0, 0.0), 2.0),)
    tasks = (Task("t", (1.0, 0.0)),)
    detour = Problem.with_paths(robots, tasks, lambda a, b: 3.0 * math.dist(a, b))
    assert detour.travel(0, None, 0) == pytest.approx(1.5)
    with pytest.raises(ConfigError, match="2 × 2"):
        Problem(robots, tasks, ((0.0,),))


coords = st.floats(-10, 10, allow_nan=False)


@settings(max_examples=60, derandomize=True, deadline=None)
@given(st.lists(st.tuples(coords, coords, st.floats(0, 30), st.floats(0, 5)), min_size=1,
                max_size=6), st.floats(0.1, 2.0))
def test_one_robot_timing_matches_a_direct_restatement(tasks, speed):
    p = Problem((Robot("r", (0.0, 0.0), speed),),
                tuple(Task(f"t{k}", (x, y), arrival=a, service=s)
                      for k, (x, y, a, s) in enumerate(tasks)))
    route = list(range(len(tasks)))
    t, here, ends, travel = 0.0, (0.0, 0.0), [], 0.0
    for x, y, a, s in tasks:
        leg = math.dist(here, (x, y)) / speed
        travel += leg
        t = max(t + leg, a) + s
        ends.append(t)
        here = (x, y)
    e = evaluate(p, {0: route})
    assert e.total_travel == pytest.approx(travel)
    assert e.flowtime == pytest.approx(sum(ends))
    assert e.makespan == pytest.approx(max(ends))
