"""HighLevel.tick's work follows the teammates that changed, not all heard, and the
incremental bookkeeping decides exactly what a rescan of every record decides.

No timing: the work is counted (`HighLevel.visits`, the records a tick looked at), and the
behaviour is compared tick by tick with the previous, rescanning implementation
(tests/harness/alliance_tick_oracle.py) on random histories (fixed seed, as the other properties).
"""

from __future__ import annotations

import os
from dataclasses import astuple

import pytest
from hypothesis import HealthCheck, given, settings, strategies as st

from robot_agent.alliance.high_level import UNKNOWN, HighLevel
from robot_agent.alliance.params import BehaviourSetParams, RobotParams
from tests.harness import alliance_tick_oracle as oracle

EXAMPLES = int(os.environ.get("MRTA_PROPERTY_EXAMPLES", "60"))
SETTINGS = settings(max_examples=EXAMPLES, derandomize=True, deadline=None,
                    suppress_health_check=[HealthCheck.too_slow])
TASKS = ("wander", "border_protection", "report")
OWN = {"r0": -3.0, "r1": UNKNOWN, "r2": 1.0, "r3": 9.0, "r4": -3.0}


def params(tau: float = 10.0, spin: float = 2.0, yielding: float = 75.0, theta: float = 100.0,
           fast: float = 5.0, tasks=TASKS) -> RobotParams:
    sets = tuple(BehaviourSetParams(t, 100.0, theta, yielding, 1000.0, fast, "x", ())
                 for t in tasks)
    return RobotParams("R", spin, 0.5, tau, 10.0, (), sets)


def visits_per_tick(heard: int, broadcasting: int, ticks: int = 12) -> list[int]:
    """Robots heard once, then `broadcasting` of them heard again between every two ticks
    (τ = 10 s and φ = 100 s do not run out meanwhile)."""
    hl = HighLevel("me", params())
    for i in range(heard):
        hl.on_broadcast(f"r{i}", TASKS[i % 3], 100.0, 0.0, active_since=-5.0)
    hl.tick(0.0)
    out = []
    for k in range(1, ticks + 1):
        now = 0.5 * k
        for i in range(broadcasting):
            j = (k * 7 + i) % heard  # a different few each tick
            hl.on_broadcast(f"r{j}", TASKS[j % 3], 100.0, now - 0.1, active_since=-5.0)
        before = hl.visits
        hl.tick(now)
        out.append(hl.visits - before)
    return out


def test_a_tick_looks_only_at_the_teammates_heard_since_the_last_one():
    assert visits_per_tick(1000, 0) == [0] * 12
    assert visits_per_tick(1000, 5) == [5] * 12
    # the same work with 10 or 1,000 heard: it does not grow with the unchanged ones
    assert visits_per_tick(10, 3) == visits_per_tick(1000, 3) == [3] * 12


def test_a_teammate_going_stale_is_looked_at_once_then_no_more():
    hl = HighLevel("me", params(tau=2.2))
    for i in range(500):
        hl.on_broadcast(f"r{i}", "wander", 100.0, 0.0)
    hl.tick(0.0)
    counts = []
    for k in range(1, 13):
        before = hl.visits
        hl.tick(0.5 * k)
        counts.append(hl.visits - before)
    # fresh until 2.2 s: one visit each at 2.5 s (they expire), then nothing; impatience fast
    # again
    assert sum(counts) == 500 and counts[-6:] == [0] * 6
    assert hl.sets["wander"].fresh == set() and hl.sets["wander"].impatience == 5.0


# ---------------------------------------------------------------- equivalence with the rescan
@st.composite
def histories(draw):
    spin = draw(st.sampled_from([1.0, 2.0, 4.0, 10.0]))
    tau = draw(st.sampled_from([1.0, 1.5, 2.0, 3.0, 5.0]))
    tau = max(tau, 2.0 / spin)
    p = params(tau=tau, spin=spin, yielding=draw(st.sampled_from([0.5, 1.0, 2.0, 4.0])),
               theta=draw(st.sampled_from([1.0, 10.0, 100.0])),
               fast=draw(st.sampled_from([0.1, 0.3, 1.0, 2.5, 10.0])), tasks=TASKS[:2])
    robots = [f"r{i}" for i in range(draw(st.integers(1, 5)))]
    steps = []
    for _ in range(draw(st.integers(20, 160))):
        heard = draw(st.lists(st.tuples(
            st.sampled_from(robots + ["r0"] * 3), st.sampled_from(TASKS[:2]),
            st.sampled_from([0.5, 2.0, 2.0, 2.0, 3.0, 7.5, 40.0, 1e9]),  # 1e9: refused
            st.sampled_from(["own"] * 8 + [UNKNOWN, -3.0, 4.5, 20.0]),
            st.floats(0.0, 0.99)), max_size=6))
        # mostly each robot's own activation (a holder heard for long: the one-way-link rule)
        heard = [(r, t, ed, OWN[r] if since == "own" else since, f)
                 for r, t, ed, since, f in heard]
        feedback = draw(st.sampled_from([(True, True), (True, True), (True, False),
                                         (False, True)]))
        gap = draw(st.sampled_from([1, 1, 1, 1, 2, 7]))  # ticks skipped (a stalled loop)
        steps.append((heard, feedback, gap))
    return p, steps


@pytest.mark.slow  # 11 s of CPU at 60 examples: the full run's, not the fast tier's
@SETTINGS
@given(histories())
def test_the_incremental_tick_decides_what_the_rescan_decides(history):
    replay(*history)


def test_the_one_way_link_rule_is_decided_as_by_the_rescan():
    """An earlier holder that keeps broadcasting and never yields (it does not hear us): we
    yield to it after ψ + 2τ + two of its intervals, again and again, as the rescan does."""
    p = params(tau=1.5, spin=2.0, yielding=1.0, theta=1.0, fast=0.5, tasks=TASKS[:2])
    # r0 heard every other tick: the delays run out on ticks it is not heard, too
    steps = [(([("r0", "wander", 2.0, -3.0, 0.0)] if k % 2 else [])
              + ([("r1", "border_protection", 3.0, 0.5, 0.3)] if k % 3 == 0 else []),
              (True, False), 1) for k in range(240)]
    reasons = [t.reason for t in replay(p, steps)]
    assert sum("it does not hear this robot" in r for r in reasons) >= 5


def replay(p: RobotParams, steps) -> list:
    """Both implementations through the same history, compared after every tick; the
    transitions."""
    transitions = []
    new, ref = HighLevel("me", p, feedback_timeout=5.0), oracle.HighLevel("me", p, 5.0)
    period = 1.0 / p.spin_rate
    now = 0.0
    for n, (heard, feedback, gap) in enumerate(steps):
        for robot, task, ed, since, frac in sorted(heard, key=lambda h: h[4]):
            at = now + frac * period * gap
            assert new.on_broadcast(robot, task, ed, at, since) == \
                ref.on_broadcast(robot, task, ed, at, since)
        now += period * gap
        for task, ok in zip(TASKS[:2], feedback):
            new.on_feedback(task, ok, now)
            ref.on_feedback(task, ok, now)
        got, want = new.tick(now), ref.tick(now)  # (the oracle's own dataclasses: as tuples)
        transitions += got[1]
        assert [[astuple(x) for x in part] for part in got] == \
            [[astuple(x) for x in part] for part in want], f"tick {n} at t={now}"
        for task in TASKS[:2]:
            a, b = new.sets[task], ref.sets[task]
            assert (a.exact_motivation, a.exact_impatience) == \
                (b.exact_motivation, b.exact_impatience)
            assert {k: (r.phi_from, r.overlap_since) for k, r in a.others.items()} == \
                {k: (r.phi_from, r.overlap_since) for k, r in b.others.items()}
    return transitions
