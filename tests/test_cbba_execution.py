"""CBBA in execution (robot_agent/cbba/agent.py): a team of CbbaCoordinators on the in-process
exchange and a manual clock (tests/harness/route_team.py) serving instances to completion; the served
orders checked against the sequential greedy assignment restated from its definition
(tests/harness/cbba_reference.greedy), which converged CBBA equals (docs/cbba.md)."""

from __future__ import annotations

import random

import pytest

from mrta_zenoh.planning import Problem, Robot, Task
from mrta_agent.cbba.agent import CbbaCoordinator
from mrta_agent.cbba.architecture import CBBA
from mrta_agent.cbba.params import CbbaKeys

from tests.harness.cbba_reference import greedy
from tests.harness.route_team import RouteTeam, params_for


def instance(seed: int, n: int = 3, m: int = 6) -> Problem:
    rng = random.Random(seed)
    robots = tuple(Robot(f"robot{i + 1}", (rng.uniform(0, 20), rng.uniform(0, 20)),
                         rng.uniform(0.5, 1.5)) for i in range(n))
    tasks = tuple(Task(f"t{j + 1}", (rng.uniform(0, 20), rng.uniform(0, 20)),
                       service=rng.choice((0.0, 1.0))) for j in range(m))
    return Problem(robots, tasks)


def team(p: Problem, progress_timeout: float = 10.0, **keys) -> RouteTeam:
    return RouteTeam(p, CBBA.messages, lambda rid, body: CbbaCoordinator(
        rid, params_for(p, CbbaKeys(**keys), progress_timeout), body))


def converged(p: Problem) -> dict[str, list[str]]:
    routes, _ = greedy(p)
    return {p.robots[i].id: [p.tasks[j].id for j in r] for i, r in routes.items()}


@pytest.mark.parametrize("seed", range(6))
def test_the_team_serves_exactly_the_plan_cbba_converges_to(seed):
    p = instance(seed)
    t = team(p)
    t.run_until_served()
    assert t.served() == converged(p)


def test_nobody_sets_off_before_its_table_has_settled():
    p = instance(1)
    t = team(p, settle=1.0)
    plan = converged(p)
    while any(c.route.current is None for c in t.coords.values()):
        t.step()
        for rid, c in t.coords.items():
            if c.route.current is not None:  # it set off: on its converged path
                assert c.logic.route() == plan[rid]


def test_same_instance_same_run():
    runs = []
    for _ in range(2):
        t = team(instance(3))
        t.run_until_served()
        runs.append(([(k, m.header.stamp, m.header.frame_id) for k, m in t.sent],
                     {r: c.route.served for r, c in t.coords.items()}))
    assert runs[0] == runs[1]


def busy_instance() -> tuple[Problem, dict[str, list[str]]]:
    for seed in range(100):
        p = instance(seed)
        plan = converged(p)
        if min(len(r) for r in plan.values()) >= 2:
            return p, plan
    raise AssertionError("no instance gives every robot two tasks")


@pytest.mark.parametrize("victim", ["robot1", "robot2"])
def test_a_crashed_robots_tasks_are_bid_on_again_and_served(victim):
    p, plan = busy_instance()
    t = team(p)
    while not t.coords[victim].route.served:
        assert t.now < 120.0
        t.step()
    t.run_until(t.now + 1.0)  # its bids saying the first one is served are out
    t.crash(victim)
    t.run_until_served()
    served = t.served()
    assert sorted(x for tasks in served.values() for x in tasks) == sorted(
        task.id for task in p.tasks)  # each exactly once
    assert served[victim] == plan[victim][:1]
    assert set(plan[victim][1:]) <= {x for r, tasks in served.items() if r != victim
                                     for x in tasks}


def test_a_stalled_robot_loses_its_tasks_to_the_others_after_the_progress_timeout():
    p, plan = busy_instance()
    t = team(p, progress_timeout=5.0)
    victim = "robot2"
    while t.coords[victim].route.current is None:
        assert t.now < 60.0
        t.step()
    stalled_at = t.now
    t.stall(victim)
    t.run_until(stalled_at + 4.0)
    assert all(c.logic.winners().get(x) == victim for c in t.coords.values()
               for x in plan[victim])  # within the timeout its tasks stay its own
    t.run_until_served()
    served = t.served()
    assert served[victim] == []
    assert sorted(x for tasks in served.values() for x in tasks) == sorted(
        task.id for task in p.tasks)
