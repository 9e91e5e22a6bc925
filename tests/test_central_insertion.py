"""central's dispatcher with many open tasks (robot_agent/central/planner.py, "Many open
tasks"; issue 50's burst of 200 submissions): above `search_limit` open tasks the plan is the
current one with each new task inserted where it adds least — no search, so no time cap and the
same plan on any machine — and the insertion values each place as the whole plan's objective
would (`full_value`), only faster (`Timing`)."""

from __future__ import annotations

import random

import pytest

from mrta_agent.central.planner import INSERTION, Situation, Timing, full_value, keep, solve
from mrta_zenoh.planning import Problem, Robot, Task
from mrta_zenoh.planning.schedule import Objective
from tests.test_planning_reference import random_problem


def windowed(seed: int, robots: int, tasks: int) -> Problem:
    """random_problem with robots ready late and some tasks opening late: stops that wait."""
    p = random_problem(seed, robots, tasks)
    rng = random.Random(seed)
    rs = tuple(Robot(r.id, r.start, r.speed, r.capabilities, ready=rng.choice([0.0, 7.5]))
               for r in p.robots)
    ts = tuple(Task(t.id, t.position, t.arrival, t.service, t.capability,
                    earliest=rng.choice([0.0, 0.0, rng.uniform(0, 60)])) for t in p.tasks)
    return Problem(rs, ts)


@pytest.mark.parametrize("seed", range(6))
def test_a_stop_inserted_anywhere_is_timed_as_the_whole_route_would_be(seed):
    p = windowed(seed, 2, 9)
    rng = random.Random(seed)
    stops = rng.sample(range(9), 6)
    for j in set(range(9)) - set(stops):
        for k in range(len(stops) + 1):
            fast = Timing(p, 0, stops).inserted(j, k)
            whole = Timing(p, 0, stops[:k] + [j] + stops[k:]).share
            assert fast == pytest.approx(whole, rel=1e-12, abs=1e-9), (j, k)


def place_by_place(problem, objective, situation, current, task_ids):
    """The insertion restated: every place valued by the whole plan's objective."""
    routes = {r: [t for t in current.get(r, ()) if t in task_ids] for r in situation.available}
    for task in task_ids:
        if any(task in route for route in routes.values()):
            continue
        trials = []
        for rid in situation.available:
            i, j = problem.robot_index(rid), problem.task_index(task)
            if problem.capable(i, j):
                for place in range(len(routes[rid]) + 1):
                    trial = {**routes, rid: routes[rid][:place] + [task] + routes[rid][place:]}
                    trials.append((full_value(problem, objective, situation.commitments,
                                              trial), len(trials), trial))
        routes = min(trials)[2]
    return routes


@pytest.mark.parametrize("objective", list(Objective))
@pytest.mark.parametrize("seed", range(4))
def test_the_insertion_is_the_whole_plans_cheapest_place_by_place(seed, objective):
    p = windowed(seed, 3, 12)
    ids = [t.id for t in p.tasks]
    situation = Situation({"r0": (ids[0],), "r1": (), "r2": ()}, ("r0", "r1", "r2"),
                          tuple(ids[1:]))
    current = {"r0": ids[1:4]}  # r0 has every capability
    assert keep(p, objective, situation, current, ids[1:]) == \
        place_by_place(p, objective, situation, current, ids[1:])


def test_above_the_search_limit_every_task_is_inserted_without_a_search():
    """A burst of 200 open tasks: planned in full, by insertion into the plan so far, not
    capped (no search ran: the same plan on any machine); at the limit the search runs."""
    p = random_problem(7, 5, 200)
    robots = tuple(r.id for r in p.robots)
    situation = Situation({r: () for r in robots}, robots, tuple(t.id for t in p.tasks))
    current = {"r1": ["t5", "t3"]}
    out = solve(p, situation, Objective.MINSUM, exact_limit=8, solutions=200, time_limit=60.0,
                search_limit=50, current=current)
    assert out.method == INSERTION and not out.capped and not out.unassigned
    assert sorted(t for route in out.routes.values() for t in route) == sorted(situation.open_tasks)
    assert out.routes["r1"][:2] == ["t5", "t3"] or out.routes["r1"].index("t5") < \
        out.routes["r1"].index("t3")  # the plan so far is kept, the new tasks put in it
    small = Situation(situation.commitments, robots, situation.open_tasks[:9])
    searched = solve(p, small, Objective.MINSUM, exact_limit=8, solutions=2, time_limit=60.0,
                     search_limit=9)
    assert searched.method != INSERTION
