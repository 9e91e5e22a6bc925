"""The reference under hard time windows (mrta_zenoh.planning.exact, "Hard time windows"): the
exact recursion equals a brute force over every assignment — each task to a capable robot or
to nobody (missed) — and every order, written here from the definitions (service starts at
max(reach, arrival, earliest), and must start by the due), on the hierarchical key: the most
tasks served, then the least objective. The routing search never serves more tasks than the
exact optimum, never starts a task outside its window, and equals it on easy cases."""

from __future__ import annotations

import itertools
import math
import os
import random

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from mrta_zenoh.planning import Problem, Robot, Task, evaluate
from mrta_zenoh.planning.reference import BEST_FOUND, EXACT, reference

OBJECTIVES = ("minsum", "makespan", "flowtime")
EXAMPLES = int(os.environ.get("MRTA_PROPERTY_EXAMPLES", "60"))  # more on demand


def windowed_problem(seed: int, robots: int, tasks: int, *, tight: float = 1.0,
                     windows: str = "hard") -> Problem:
    """Random robots and tasks, most with a window [earliest, due] of width ~ 12 s / `tight`
    opening within the first 20 s (some with a due only, some with none)."""
    rng = random.Random(seed)
    rs = tuple(Robot(f"r{i}", (rng.uniform(-5, 5), rng.uniform(-4, 4)), rng.uniform(0.3, 0.9),
                     frozenset(c for c in ("lift",) if i == 0 or rng.random() < 0.5))
               for i in range(robots))
    ts = []
    for j in range(tasks):
        earliest = round(rng.uniform(0, 20), 2) if rng.random() < 0.7 else 0.0
        arrival = rng.choice([0.0, 0.0, round(rng.uniform(0, earliest + 1), 2)])
        opens = max(arrival, earliest)
        due = math.inf if rng.random() < 0.15 else round(opens + rng.uniform(2, 14) / tight, 2)
        ts.append(Task(f"t{j}", (rng.uniform(-5, 5), rng.uniform(-4, 4)), arrival=arrival,
                       service=round(rng.uniform(0, 3), 2),
                       capability=rng.choice(["", "", "", "lift"]), earliest=earliest, due=due))
    return Problem(rs, tuple(ts), windows=windows)


def brute_force(p: Problem, objective: str) -> tuple[int, float]:
    """(most tasks served within their windows, least value among those) over every map of
    tasks to a capable robot or to nobody and every order on each robot."""
    m, n = len(p.robots), len(p.tasks)
    best_key = (1, 0.0)  # worse than any
    for owner in itertools.product(range(-1, m), repeat=n):
        if any(o >= 0 and p.tasks[j].capability
               and p.tasks[j].capability not in p.robots[o].capabilities
               for j, o in enumerate(owner)):
            continue
        served = sum(o >= 0 for o in owner)
        if -served > best_key[0]:
            continue
        per_robot = [[j for j in range(n) if owner[j] == i] for i in range(m)]
        for orders in itertools.product(*(itertools.permutations(s) for s in per_robot)):
            travel, ends, ok = 0.0, [], True
            for i, order in enumerate(orders):
                t, here = 0.0, i
                for j in order:
                    task = p.tasks[j]
                    leg = p.distance[here][m + j] / p.robots[i].speed
                    travel += leg
                    start = max(t + leg, task.arrival, task.earliest)
                    if start > task.due:
                        ok = False
                        break
                    t = start + task.service
                    ends.append(t)
                    here = m + j
                if not ok:
                    break
            if not ok:
                continue
            value = (travel if objective == "minsum" else
                     max(ends, default=0.0) if objective == "makespan" else sum(ends))
            best_key = min(best_key, (-served, value))
    return -best_key[0], best_key[1]


def check_in_windows(p: Problem, routes) -> None:
    for v in evaluate(p, routes).visits:
        task = p.tasks[v.task]
        assert task.opens <= v.start <= task.due, (task, v)


@settings(max_examples=EXAMPLES, derandomize=True, deadline=None,
          suppress_health_check=[HealthCheck.too_slow])
@given(seed=st.integers(0, 10 ** 6), robots=st.integers(1, 2), tasks=st.integers(1, 5),
       tight=st.sampled_from([0.5, 1.0, 3.0]), objective=st.sampled_from(OBJECTIVES))
def test_exact_equals_brute_force_under_hard_windows(seed, robots, tasks, tight, objective):
    p = windowed_problem(seed, robots, tasks, tight=tight)
    ref = reference(p, objective)
    served, value = brute_force(p, objective)
    assert ref.method == EXACT and ref.proven_optimal
    assert ref.served == served
    assert ref.value == pytest.approx(value, abs=1e-9)
    check_in_windows(p, ref.routes)
    assert evaluate(p, ref.routes).value(objective) == pytest.approx(ref.value, abs=1e-12)


@pytest.mark.parametrize("objective", OBJECTIVES)
def test_three_robots_six_tasks_tight_windows(objective):
    """A case where windows bind (some task missed) checked against the brute force."""
    for seed in range(40):
        p = windowed_problem(seed, 3, 6, tight=3.0)
        ref = reference(p, objective)
        if ref.served < len(p.tasks):
            break
    else:
        pytest.fail("no seed gave a windowed instance with a missed task")
    assert (ref.served, pytest.approx(ref.value, abs=1e-9)) == brute_force(p, objective)


def test_soft_windows_serve_every_task_and_wait_for_earliest():
    p = windowed_problem(7, 2, 5, tight=3.0, windows="soft")
    ref = reference(p, "minsum")
    assert ref.served == len(p.tasks)
    for v in evaluate(p, ref.routes).visits:
        assert v.start >= p.tasks[v.task].opens


@pytest.mark.parametrize("objective", ("minsum", "makespan"))
def test_routing_never_beats_the_exact_hierarchy_and_keeps_windows(objective):
    for seed in range(2):
        p = windowed_problem(100 + seed, 3, 7, tight=1.0)
        exact = reference(p, objective)
        found = reference(p, objective, exact_limit=0, solutions=100)
        assert found.method == BEST_FOUND and not found.proven_optimal
        check_in_windows(p, found.routes)
        assert found.served <= exact.served
        if found.served == exact.served:
            assert found.value >= exact.value - 1e-9


def test_pyvrp_matches_the_exact_hierarchy_on_a_small_case_and_solves_minsum_only():
    from mrta_zenoh.errors import ConfigError
    from mrta_zenoh.planning.pyvrp_routing import solve_pyvrp

    p = windowed_problem(3, 2, 6, tight=3.0)
    exact = reference(p, "minsum")
    found = solve_pyvrp(p, iterations=300)
    check_in_windows(p, found.routes)
    ev = evaluate(p, found.routes)
    assert (ev.served, pytest.approx(ev.total_travel, abs=1e-6)) == (exact.served, exact.value)
    with pytest.raises(ConfigError, match="MinSum"):
        solve_pyvrp(p, "makespan")
