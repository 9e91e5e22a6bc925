"""central on virtual time (tests/harness/central_team.py: the real dispatcher and robot logic in the real
agent driver, on the in-process bus and a manual clock, kinematic robots): the executed routes
are the optimum (computed here by brute force, timing re-implemented), a crashed or stalled
robot's tasks go to the others, the dispatcher's crash leaves robots finishing their queues,
late tasks wait for their arrival, and no task is ever executed by two robots at once — under
loss, latency and partitions too."""

from __future__ import annotations

import itertools
import math
import random

import pytest
from hypothesis import HealthCheck, given, settings, strategies as st

from mrta_agent.central.dispatcher import Dispatcher
from mrta_agent.central.messages import Progress
from mrta_agent.central.params import DispatcherParams
from mrta_zenoh.failure import FaultPlan
from mrta_zenoh.messages import Header
from mrta_zenoh.planning import Problem, Robot, Task
from tests.harness.central_team import Team


# ------------------------------------------------------------------ the definitions, restated
def timing(problem: Problem, robot: str, route: list[str]) -> tuple[float, list[float]]:
    """(travel, completions) of `robot` serving `route` from its start at 0: straight lines at
    its speed, waiting for arrivals, staying the service time (docs/delivery.md, Objectives)."""
    r = next(x for x in problem.robots if x.id == robot)
    at, now, travel, ends = r.start, 0.0, 0.0, []
    for tid in route:
        t = next(x for x in problem.tasks if x.id == tid)
        leg = math.dist(at, t.position) / r.speed
        travel += leg
        now = max(now + leg, t.arrival) + t.service
        ends.append(now)
        at = t.position
    return travel, ends


def value(problem: Problem, routes: dict[str, list[str]], objective: str) -> float:
    parts = [timing(problem, r, route) for r, route in routes.items()]
    if objective == "minsum":
        return sum(travel for travel, _ in parts)
    if objective == "makespan":
        return max((max(ends) for _, ends in parts if ends), default=0.0)
    return sum(sum(ends) for _, ends in parts)


def brute_force(problem: Problem, objective: str) -> float:
    """The optimum over every assignment of tasks to capable robots and every order."""
    robots = [r.id for r in problem.robots]
    best = math.inf
    for owners in itertools.product(robots, repeat=len(problem.tasks)):
        if any(t.capability and t.capability not in problem.robots[robots.index(o)].capabilities
               for t, o in zip(problem.tasks, owners)):
            continue
        per = {r: [t.id for t, o in zip(problem.tasks, owners) if o == r] for r in robots}
        total = 0.0 if objective != "makespan" else -math.inf
        for r, mine in per.items():
            one = min(value(problem, {r: list(p)}, objective)
                      for p in itertools.permutations(mine)) if mine else 0.0
            total = max(total, one) if objective == "makespan" else total + one
        best = min(best, total)
    return best


def instance(seed: int, robots: int, tasks: int, late: float = 0.0) -> Problem:
    rng = random.Random(seed)
    return Problem(
        tuple(Robot(f"robot{i + 1}", (rng.uniform(-5, 5), rng.uniform(-4, 4)),
                    round(rng.uniform(0.4, 0.8), 2)) for i in range(robots)),
        tuple(Task(f"t{j + 1}", (rng.uniform(-5, 5), rng.uniform(-4, 4)),
                   arrival=round(rng.uniform(0, late), 1) if late else 0.0,
                   service=round(rng.uniform(1, 3), 1)) for j in range(tasks)))


SQUARE = Problem(
    (Robot("robot1", (0.0, 0.0), 0.5), Robot("robot2", (10.0, 0.0), 0.5)),
    (Task("t1", (1.0, 0.0), service=1.0), Task("t2", (2.0, 0.0), service=1.0),
     Task("t3", (9.0, 0.0), service=1.0), Task("t4", (5.0, 0.0), service=2.0)))


# ------------------------------------------------------------------ no fault: the optimum
@pytest.mark.parametrize("objective", ["minsum", "makespan", "flowtime"])
@pytest.mark.parametrize("problem", [SQUARE, instance(3, 3, 5)], ids=["line", "random"])
def test_a_static_instance_is_served_along_optimal_routes(problem, objective):
    team = Team(problem, DispatcherParams(objective=objective))
    team.until(team.all_served)
    routes = team.routes()
    assert sorted(team.served_tasks()) == sorted(t.id for t in problem.tasks)
    assert value(problem, routes, objective) == pytest.approx(
        brute_force(problem, objective), abs=1e-9)
    d = team.dispatcher
    # planned once, then every completion re-solved and the plan kept (an exact optimum ties)
    assert d.decisions[0].trigger == "start"
    assert all(x.outcome.method == "kept" for x in d.decisions[1:])
    assert not team.simultaneous()


def test_what_the_dispatcher_plans_is_what_the_run_reports():
    team = Team(SQUARE)
    team.until(team.all_served)
    first = team.dispatcher.decisions[0].outcome
    assert first.value == pytest.approx(value(SQUARE, team.routes(), "minsum"), abs=1e-9)
    assert first.routes == team.routes()


# ------------------------------------------------------------------ losses
def test_a_crashed_robots_tasks_are_replanned_within_two_ticks_and_served_once():
    team = Team(SQUARE)
    team.step(20)
    queues = {r: team.agents[r].coordinator.route.queue for r in ("robot1", "robot2")}
    victim = max(queues, key=lambda r: len(queues[r]))
    other = next(r for r in queues if r != victim)
    lost = set(queues[victim])
    assert len(lost) >= 2
    team.kill(victim)
    team.step(2)  # the dispatcher's tick learns it and re-plans; the other's tick hears it
    assert lost <= set(team.agents[other].coordinator.route.queue)
    team.until(team.all_served)
    assert not team.simultaneous()
    assert sorted(team.served_tasks()) == ["t1", "t2", "t3", "t4"]  # each exactly once


def test_a_stalled_robot_loses_its_tasks_after_the_progress_timeout():
    params = DispatcherParams(progress_timeout=5.0)
    team = Team(SQUARE, params)
    team.step(30)  # robot2 is on its way (t3 is 1 m off: there and serving by now)
    stalled = set(team.agents["robot2"].coordinator.route.queue)
    assert stalled
    team.bodies["robot2"].stalled = True
    t_stall = team.clock.now()
    team.until(lambda: team.dispatcher.robots["robot2"].lost == "stalled", limit=20)
    assert team.clock.now() - t_stall >= params.progress_timeout
    team.until(team.all_served)
    assert not team.simultaneous()
    served_by_2 = [t for t, _ in team.served.get("robot2", [])]
    assert set(team.routes()["robot1"]) >= stalled - set(served_by_2)
    assert team.agents["robot2"].coordinator.route.queue == []  # it gave them back


def test_robots_finish_their_queues_when_the_dispatcher_crashes_and_nothing_new_is_served():
    late = Task("t5", (4.0, 1.0), arrival=30.0, service=1.0)
    problem = Problem(SQUARE.robots, SQUARE.tasks + (late,))
    team = Team(problem)
    team.step(20)
    queues = {r: list(team.agents[r].coordinator.route.queue) for r in ("robot1", "robot2")}
    team.kill("dispatcher")
    team.until(lambda: len(team.served_tasks()) == 4)
    assert team.routes() == {r: q for r, q in queues.items() if q}  # each its own queue
    assert sorted(team.served_tasks()) == ["t1", "t2", "t3", "t4"]
    team.step(400)  # t5 arrives at 30 s: nobody plans it
    assert "t5" not in team.served_tasks()
    assert all(not team.agents[r].coordinator.route.queue for r in ("robot1", "robot2"))


def test_a_late_task_is_planned_at_its_arrival_and_not_before():
    late = Task("t5", (8.0, 1.0), arrival=12.0, service=1.0)
    problem = Problem(SQUARE.robots, SQUARE.tasks + (late,))
    team = Team(problem)
    team.until(lambda: "t5" in team.served_tasks())
    first = min(t for t, _robot, task in team.active_log if task == "t5")
    assert first >= 12.0 - 1e-6  # the manual clock adds 0.1 s steps: 11.999… is 12
    assert any(d.trigger == "arrival" and d.at >= 12.0 - 1e-6
               for d in team.dispatcher.decisions)


# ------------------------------------------------------------------ no task executed twice
@pytest.mark.parametrize("seed", [1, 2, 3])
def test_loss_and_latency_never_let_two_robots_execute_one_task(seed):
    problem = instance(seed, 3, 6, late=20.0)
    plans = {name: FaultPlan(name, seed, loss=0.3, latency=(0.3, 0.2))
             for name in [r.id for r in problem.robots] + ["dispatcher"]}
    team = Team(problem, faults=plans)
    team.until(team.all_served, limit=400)
    assert not team.simultaneous()
    assert sorted(team.served_tasks()) == sorted(t.id for t in problem.tasks)


def test_a_cut_off_robot_holds_before_its_tasks_go_to_another():
    # robot2's one task is 6 s away: cut off at 2 s it holds (lease) on its way, the
    # dispatcher gives up on it (progress_timeout) and gives the task to robot1
    far = Problem(SQUARE.robots, (Task("t1", (1.0, 0.0), service=1.0),
                                  Task("t2", (2.0, 0.0), service=1.0),
                                  Task("t3", (7.0, 0.0), service=1.0)))
    plans = {"robot2": FaultPlan("robot2", 0, partitions=((2.0, 40.0),))}
    team = Team(far, faults=plans)
    team.step(1)
    assert team.dispatcher.plan["robot2"] == ["t3"]
    team.until(team.all_served, limit=300)
    assert not team.simultaneous()
    assert sorted(team.served_tasks()) == ["t1", "t2", "t3"]
    assert team.routes()["robot1"][-1] == "t3"
    assert any(d.trigger == "loss" for d in team.dispatcher.decisions)
    team.step(300)  # the partition heals: robot2 hears its empty queue and leaves t3
    assert team.agents["robot2"].coordinator.route.queue == []
    assert sorted(team.served_tasks()) == ["t1", "t2", "t3"]


@pytest.mark.parametrize("back_at", [16.0, 20.0])
def test_a_robot_back_from_a_partition_with_a_task_granted_meanwhile_does_not_break_the_plan(
        back_at):
    """robot2, cut off from 2 s, is re-planned out at 11.1 s and t3 granted to robot1; back at
    `back_at` it still reports t3. One of the two keeps it — the dispatcher does not stop on
    two routes holding one task (it raised there) — and nobody serves it twice at once."""
    far = Problem(SQUARE.robots, (Task("t1", (1.0, 0.0), service=1.0),
                                  Task("t2", (2.0, 0.0), service=1.0),
                                  Task("t3", (7.0, 0.0), service=1.0)))
    team = Team(far, faults={"robot2": FaultPlan("robot2", 0, partitions=((2.0, back_at),))})
    team.until(team.all_served, limit=600)
    assert [d.trigger for d in team.dispatcher.decisions][3:5] == ["loss", "return"]
    assert sorted(team.served_tasks()) == ["t1", "t2", "t3"] and not team.simultaneous()


FAULTS = st.sampled_from(["none", "crash", "stall", "partition"])


@settings(max_examples=12, deadline=None, derandomize=True,
          suppress_health_check=[HealthCheck.too_slow])
@given(seed=st.integers(0, 10_000), robots=st.integers(2, 3), tasks=st.integers(2, 6),
       fault=FAULTS, loss=st.sampled_from([0.0, 0.2]), at=st.integers(10, 80))
def test_no_task_is_ever_executed_by_two_robots(seed, robots, tasks, fault, loss, at):
    problem = instance(seed, robots, tasks, late=15.0)
    victim = problem.robots[seed % robots].id
    plans = {name: FaultPlan(name, seed, loss=loss,
                             partitions=((at * 0.1, at * 0.1 + 15.0),)
                             if fault == "partition" and name == victim else ())
             for name in [r.id for r in problem.robots] + ["dispatcher"]}
    team = Team(problem, DispatcherParams(progress_timeout=6.0), faults=plans)
    team.step(at)
    if fault == "crash":
        team.kill(victim)
    elif fault == "stall":
        team.bodies[victim].stalled = True
    team.until(team.all_served, limit=600)
    assert not team.simultaneous()
    assert sorted(team.served_tasks()) == sorted(t.id for t in problem.tasks)


# ------------------------------------------------------------------ the grant rule, message by message
def progress(task: str, queue: tuple[str, ...], version: int, x: float, served=()) -> Progress:
    return Progress(Header("", 0.0, 0), task, "", queue, tuple(served), x, 0.0, 0.0, version)


def queues(out) -> dict[str, tuple[str, ...]]:
    return {s.fields["robot"]: s.fields["tasks"] for s in out if s.kind == "queue"}


def test_a_task_another_robot_may_still_serve_is_not_granted_until_it_lets_go():
    d = Dispatcher(SQUARE, DispatcherParams(progress_timeout=5.0))
    d.teammate("robot1", True)
    d.teammate("robot2", True)
    sent = queues(d.tick(0.0))
    assert sent == {"robot1": ("t1", "t2", "t4"), "robot2": ("t3",)}
    v1 = d.sent["robot1"].version
    # robot1 sets off to t1 and never moves again; robot2 serves t3 and stays idle there
    d.hear("progress", "robot1", progress("t1", ("t1", "t2", "t4"), v1, 0.0), 0.1)
    d.hear("progress", "robot2", progress("", (), d.sent["robot2"].version, 9.0, ["t3"]), 3.0)
    now = 0.2
    while d.robots["robot1"].lost is None:
        d.hear("progress", "robot1", progress("t1", ("t1", "t2", "t4"), v1, 0.0), now)
        out = d.tick(now)
        now = round(now + 0.1, 1)
    assert d.robots["robot1"].lost == "stalled"
    assert d.plan["robot2"] == ["t4", "t2", "t1"]           # re-planned onto robot2 (at 9 m) ...
    assert queues(out).get("robot1") == ()
    assert not d.queue_for("robot2")                        # ... not granted: robot1 holds them
    d.hear("progress", "robot1", progress("t1", ("t1",), v1, 0.0), now)  # it lets go of t2, t4
    assert d.queue_for("robot2") == ("t4", "t2")            # cut before t1: robot1 is on it
    d.hear("progress", "robot1", progress("", (), d.sent["robot1"].version, 0.0), now)
    assert d.queue_for("robot2") == ("t4", "t2", "t1")


def test_the_robot_a_task_was_granted_to_keeps_it_when_the_robot_cut_off_from_it_comes_back():
    """robot2 sets off to t1 and goes silent; t1 goes to robot1, which sets off; robot2 comes
    back still reporting t1. robot1 keeps it in its queue (it is already on it: withholding
    it would leave t1 to nobody until some other event re-planned), robot2 is sent none."""
    problem = Problem((Robot("robot1", (0.0, 0.0), 0.5), Robot("robot2", (10.0, 0.0), 0.5)),
                      (Task("t1", (9.0, 0.0), service=1.0),))
    d = Dispatcher(problem, DispatcherParams(progress_timeout=5.0))
    d.teammate("robot1", True)
    d.teammate("robot2", True)
    assert queues(d.tick(0.0)) == {"robot1": (), "robot2": ("t1",)}
    d.hear("progress", "robot2", progress("t1", ("t1",), d.sent["robot2"].version, 10.0), 0.1)
    now = 0.2
    while d.robots["robot2"].lost is None:  # robot2 silent from here on
        d.hear("progress", "robot1", progress("", (), d.sent["robot1"].version, 0.0), now)
        d.tick(now)
        now = round(now + 0.1, 1)
    assert d.robots["robot2"].lost == "silent" and d.queue_for("robot1") == ("t1",)
    x = 0.0
    for _ in range(3):  # robot1 sets off
        x += 0.05
        d.hear("progress", "robot1", progress("t1", ("t1",), d.sent["robot1"].version, x), now)
        d.tick(now)
        now = round(now + 0.1, 1)
    d.hear("progress", "robot2", progress("t1", ("t1",), d.sent["robot2"].version, 9.6), now)
    for _ in range(100):
        x += 0.05
        d.hear("progress", "robot1", progress("t1", ("t1",), d.sent["robot1"].version, x), now)
        d.tick(now)
        now = round(now + 0.1, 1)
        assert d.queue_for("robot1") == ("t1",) and d.queue_for("robot2") == ()
    assert d.sent["robot1"].tasks == ("t1",) and d.sent["robot2"].tasks == ()
