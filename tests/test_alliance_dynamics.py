"""Motivation dynamics on virtual time, against traces computed by hand (appendix E)."""

import logging
import math

import pytest

from mrta_agent.alliance.high_level import HighLevel
from tests.harness.alliance_fixtures import bset, robot


def run(hl, t0, ticks, applicable=True, others=(), spin=1.0):
    """Tick `ticks` times from t0; `others`: (robot, task, expected[, active_since]) broadcast
    before each tick."""
    out = []
    for i in range(ticks):
        now = t0 + i / spin
        for task in hl.sets:
            hl.on_feedback(task, applicable, now)
        for rid, task, expected, *since in others:
            hl.on_broadcast(rid, task, expected, now, *since)
        states, transitions = hl.tick(now)
        out.append(({s.task_id: s for s in states}, transitions))
    return out


def test_first_activation_after_ceil_theta_over_fast_ticks():
    hl = HighLevel("r1", robot(bset("wander", theta=150.0, fast=7.0)))
    trace = run(hl, 0.0, 30)
    first = next(i for i, (st, _) in enumerate(trace) if st["wander"].active)
    assert first + 1 == math.ceil(150 / 7)  # 22nd tick
    assert [st["wander"].motivation for st, _ in trace[:3]] == [7.0, 14.0, 21.0]
    assert trace[first][1][0].reason == "threshold reached"


def test_motivation_saturates_at_threshold_while_active():
    hl = HighLevel("r1", robot(bset("wander", theta=100.0, fast=30.0, giving_up=1000, yielding=1000)))
    trace = run(hl, 0.0, 10)
    assert [st["wander"].motivation for st, _ in trace] == [30, 60, 90] + [100.0] * 7
    assert all(st["wander"].active for st, _ in trace[3:])


def test_slow_rate_while_another_robot_is_fresh_then_fast_when_it_stops():
    # θ=100, ρ=2 Hz, other robot announces expected_duration 25 s → slow = 100/(25·2) = 2 per tick
    hl = HighLevel("r1", robot(bset("border", theta=100.0, fast=10.0), spin=2.0, tau=3.0))
    trace = run(hl, 0.0, 6, others=[("r2", "border", 25.0)], spin=2.0)
    imp = [st["border"].impatience for st, _ in trace]
    mot = [st["border"].motivation for st, _ in trace]
    assert imp == [2.0] * 6
    assert trace[0][0]["border"].resetted and mot[0] == 0.0  # r2 newly started: reset
    assert mot[1:] == [2.0, 4.0, 6.0, 8.0, 10.0]
    # r2 falls silent at t=2.5; its broadcasts are fresh until t=5.5 (τ=3), then fast again
    later = run(hl, 3.0, 8, spin=2.0)
    imp = [st["border"].impatience for st, _ in later]
    assert imp == [2.0] * 6 + [10.0] * 2  # t=3.0…5.5 slow, t=6.0 and 6.5 fast
    assert [st["border"].motivation for st, _ in later][-2:] == [32.0, 42.0]


def test_slow_above_fast_warns_once(caplog):
    hl = HighLevel("r1", robot(bset("t", theta=1000.0, fast=10.0)))
    with caplog.at_level(logging.WARNING, logger="mrta.alliance"):
        trace = run(hl, 0.0, 5, others=[("r2", "t", 5.0)])
    # slow = 1000 / (5 s · 1 Hz) = 200 per tick > fast 10 → fast is used, never a crash
    assert all(st["t"].impatience == 10.0 for st, _ in trace)
    assert len([r for r in caplog.records if "exceeds fast_rate" in r.getMessage()]) == 1


def test_phi_expiry_switches_back_to_fast():
    # slow = 100/(4·1) = 25 ≤ fast 50; after r2 has broadcast for its expected 4 s → fast
    hl = HighLevel("r1", robot(bset("t", theta=100.0, fast=50.0), spin=1.0, tau=5.0))
    trace = run(hl, 0.0, 6, others=[("r2", "t", 4.0)])
    assert [st["t"].impatience for st, _ in trace] == [25.0] * 4 + [50.0] * 2


def test_an_active_robot_is_not_reset_by_a_newcomer_and_yields_to_it_after_more_than_psi():
    # Active from t=1 (θ=20, fast=10 → 2 ticks). r2 starts the task at t=2 (active_since 2).
    hl = HighLevel("r1", robot(bset("t", theta=20.0, fast=10.0, yielding=4.0, giving_up=100.0)))
    run(hl, 0.0, 2)
    assert hl.sets["t"].active and hl.sets["t"].activated_at == 1.0
    trace = run(hl, 2.0, 5, others=[("r2", "t", 1000.0, 2.0)])
    actives = [st["t"].active for st, _ in trace]
    # active for 1, 2, 3, 4 s at t=2…5: not *more than* ψ=4 (E.5); at t=6, 5 s > 4 → yields
    assert actives == [True, True, True, True, False]
    assert not any(st["t"].resetted for st, _ in trace)  # E.4 does not apply to an active set
    (switch,) = trace[4][1]
    assert switch.reason.startswith("yielded to r2") and trace[4][0]["t"].acquiescent
    assert trace[4][0]["t"].motivation == 0.0


def test_the_later_holder_keeps_the_task():
    # r1 active from t=1; r2 reports it has been active since t=0.5 (earlier): r1 keeps
    hl = HighLevel("r1", robot(bset("t", theta=20.0, fast=10.0, yielding=1.0, giving_up=100.0)))
    run(hl, 0.0, 2)
    trace = run(hl, 2.0, 6, others=[("r2", "t", 1000.0, 0.5)])
    assert all(st["t"].active for st, _ in trace)


def test_same_start_ties_break_by_robot_id():
    # ordered by (start, id): (1.0, "r2") comes after (1.0, "r1") — r2 keeps, r1 yields
    for me, other, keeps in (("r1", "r2", False), ("r3", "r2", True)):
        hl = HighLevel(me, robot(bset("t", theta=20.0, fast=10.0, yielding=1.0, giving_up=100.0)))
        run(hl, 0.0, 2)  # active from t=1
        trace = run(hl, 2.0, 2, others=[(other, "t", 1000.0, 1.0)])
        assert trace[-1][0]["t"].active is keeps


def test_give_up_after_more_than_lambda_even_alone():
    hl = HighLevel("r1", robot(bset("t", theta=20.0, fast=10.0, yielding=1.0, giving_up=5.0)))
    trace = run(hl, 0.0, 11)
    actives = [st["t"].active for st, _ in trace]
    # active at t=1; active for exactly λ=5 s at t=6 (kept), 6 s at t=7 → gives up (E.5 ">");
    # motivation restarts: 10 at t=8, 20 → active at t=9
    assert actives == [False, True, True, True, True, True, True, False, False, True, True]
    (switch,) = trace[7][1]
    assert switch.reason.startswith("gave up after 6.0 s") and not switch.active


def test_the_switch_off_tick():
    # the tick where the active set switches off publishes motivation 0, active False,
    # acquiescent True, and the previous tick still showed it active at θ
    hl = HighLevel("r1", robot(bset("t", theta=20.0, fast=10.0, yielding=1.0, giving_up=2.0)))
    trace = run(hl, 0.0, 5)
    before, off = trace[3][0]["t"], trace[4][0]["t"]
    assert (before.active, before.motivation, before.acquiescent) == (True, 20.0, False)
    assert (off.active, off.motivation, off.acquiescent) == (False, 0.0, True)


def test_reset_once_for_each_new_activation_not_for_late_or_lost_broadcasts():
    hl = HighLevel("r1", robot(bset("t", theta=1000.0, fast=10.0), tau=2.0))
    resets = []
    for i in range(20):
        now = float(i)
        hl.on_feedback("t", True, now)
        if 2 <= i < 15 and i not in (8, 9, 10):  # r2's broadcasts lost 4 s (> τ): same activation
            hl.on_broadcast("r2", "t", 500.0, now, 2.0)
        if 6 <= i:
            hl.on_broadcast("r3", "t", 500.0, now + 0.01, 6.0)  # jittered
        if i >= 15:
            hl.on_broadcast("r2", "t", 500.0, now, 15.0)  # r2 started anew
        states, _ = hl.tick(now)
        resets.append(states[0].resetted)
    assert [i for i, r in enumerate(resets) if r] == [2, 6, 15]


def test_a_sender_without_active_since_is_new_only_after_a_long_lapse():
    hl = HighLevel("r1", robot(bset("t", theta=1000.0, fast=10.0), tau=2.0))
    resets = []
    for i in range(16):
        now = float(i)
        hl.on_feedback("t", True, now)
        # every 2 s, +10 ms of latency on every other one: gaps of 2.01 s > τ = 2 s, but within
        # 1.5 × its own interval; then silent 6 s (> τ and > 1.5 × 2 s): a new start at 14
        if i <= 8 and i % 2 == 0:
            hl.on_broadcast("r2", "t", 500.0, now + (0.01 if i % 4 else 0.0))
        if i == 14:
            hl.on_broadcast("r2", "t", 500.0, now)
        states, _ = hl.tick(now + 0.02)
        resets.append(states[0].resetted)
    assert [i for i, r in enumerate(resets) if r] == [0, 14]


@pytest.mark.parametrize("expected", [0.0, -5.0, 1e300, math.inf])
def test_absurd_expected_durations_are_refused(expected):
    hl = HighLevel("r1", robot(bset("t", theta=100.0, fast=10.0)))
    assert hl.on_broadcast("r2", "t", expected, 0.0) is False
    assert hl.sets["t"].others == {}
    trace = run(hl, 0.0, 3)
    assert [st["t"].impatience for st, _ in trace] == [10.0] * 3  # impatience not frozen


def test_suppression_one_active_set_at_a_time():
    hl = HighLevel("r1", robot(bset("a", theta=30.0, fast=10.0, giving_up=100, yielding=100),
                               bset("b", theta=40.0, fast=10.0, giving_up=100, yielding=100)))
    trace = run(hl, 0.0, 8)
    assert trace[2][0]["a"].active  # 3 ticks
    for st, _ in trace[3:]:
        assert st["a"].active and not st["b"].active
        assert st["b"].suppressed and st["b"].motivation == 0.0


def test_a_true_simultaneous_threshold_crossing_picks_the_furthest_past_its_threshold():
    # both cross on tick 2: a at 24/20 = 1.2 θ, b at 22/20 = 1.1 θ → a wins, b suppressed
    for order in (("a", "b"), ("b", "a")):
        sets = {"a": bset("a", theta=20.0, fast=12.0), "b": bset("b", theta=20.0, fast=11.0)}
        hl = HighLevel("r1", robot(*(sets[k] for k in order)))
        trace = run(hl, 0.0, 3)
        st, switches = trace[1]
        assert [(s.task_id, s.active) for s in switches] == [("a", True)]
        assert st["a"].active and st["a"].motivation == 20.0
        assert st["b"].suppressed and st["b"].motivation == 0.0 and not st["b"].active


def test_suppression_uses_the_previous_ticks_activity_whatever_the_order():
    # a (active from t=0) gives up at t=3 (active 3 s > λ=2); on that tick b is still
    # suppressed — a was active when the tick began — whichever set is listed first
    traces = []
    for order in (("a", "b"), ("b", "a")):
        sets = {"a": bset("a", theta=20.0, fast=20.0, giving_up=2.0, yielding=100.0),
                "b": bset("b", theta=20.0, fast=10.0, giving_up=100.0, yielding=100.0)}
        hl = HighLevel("r1", robot(*(sets[k] for k in order)))
        trace = run(hl, 0.0, 6)
        assert [st["a"].active for st, _ in trace][:4] == [True, True, True, False], order
        assert trace[3][0]["b"].suppressed and trace[3][0]["b"].motivation == 0.0, order
        traces.append([(st["a"], st["b"]) for st, _ in trace])
    assert traces[0] == traces[1]


def test_inapplicable_deactivates_and_zeroes():
    hl = HighLevel("r1", robot(bset("t", theta=20.0, fast=10.0, giving_up=100, yielding=100)))
    run(hl, 0.0, 3)
    assert hl.sets["t"].active
    trace = run(hl, 3.0, 1, applicable=False)
    assert trace[0][1][0].reason == "inapplicable"
    assert trace[0][0]["t"].motivation == 0.0


def test_stale_feedback_makes_a_set_inapplicable():
    hl = HighLevel("r1", robot(bset("t", theta=1000.0, fast=10.0)), feedback_timeout=2.0)
    hl.on_feedback("t", True, 0.0)
    assert [hl.tick(float(t))[0][0].applicable for t in range(4)] == [True, True, True, False]


def test_own_broadcasts_are_ignored():
    hl = HighLevel("r1", robot(bset("t", theta=100.0, fast=10.0)))
    trace = run(hl, 0.0, 3, others=[("r1", "t", 10.0)])
    assert [st["t"].impatience for st, _ in trace] == [10.0] * 3
