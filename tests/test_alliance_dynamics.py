"""Motivation dynamics on virtual time, against traces computed by hand (appendix E)."""

import logging
import math

from robot_agent.high_level import HighLevel
from tests.alliance_fixtures import bset, robot


def run(hl, t0, ticks, applicable=True, others=(), spin=1.0):
    """Tick `ticks` times from t0; `others`: (robot, task, expected) broadcast before each tick."""
    out = []
    for i in range(ticks):
        now = t0 + i / spin
        for task in hl.sets:
            hl.on_feedback(task, applicable, now)
        for rid, task, expected in others:
            hl.on_broadcast(rid, task, expected, now)
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


def test_yield_and_give_up_timing():
    # Active from t=1 (θ=20, fast=10). Another robot appears at t=2 and keeps broadcasting.
    hl = HighLevel("r1", robot(bset("t", theta=20.0, fast=10.0, yielding=4.0, giving_up=100.0)))
    run(hl, 0.0, 2)
    assert hl.sets["t"].active and hl.sets["t"].activated_at == 1.0
    trace = run(hl, 2.0, 4, others=[("r2", "t", 1000.0)])
    # reset at t=2 (r2 newly started) deactivates immediately
    assert trace[0][1][0].reason == "reset" and not trace[0][0]["t"].active


def test_yield_when_other_robot_already_known():
    hl = HighLevel("r1", robot(bset("t", theta=20.0, fast=10.0, yielding=4.0, giving_up=100.0)))
    hl.sets["t"].active, hl.sets["t"].activated_at, hl.sets["t"].motivation = True, 0.0, 20.0
    hl.on_broadcast("r2", "t", 1000.0, 0.0)
    hl.sets["t"].others["r2"].fresh_at_last_tick = True  # already known: no reset
    trace = run(hl, 1.0, 5, others=[("r2", "t", 1000.0)])
    actives = [st["t"].active for st, _ in trace]
    assert actives == [True, True, True, False, False]  # active for 4 s at t=4 → yields
    assert trace[3][1][0].reason == "acquiesced (yielded)"
    assert trace[3][0]["t"].acquiescent


def test_give_up_after_lambda_even_alone():
    hl = HighLevel("r1", robot(bset("t", theta=20.0, fast=10.0, yielding=1.0, giving_up=5.0)))
    trace = run(hl, 0.0, 10)
    actives = [st["t"].active for st, _ in trace]
    # active at t=1, gives up at t=6 (active 5 s), motivation restarts: 10 at t=7, active at t=8
    assert actives == [False, True, True, True, True, True, False, False, True, True]
    assert trace[6][1][0].reason == "gave up"


def test_reset_once_for_each_newly_started_robot():
    hl = HighLevel("r1", robot(bset("t", theta=1000.0, fast=10.0), tau=2.0))
    resets = []
    for i in range(12):
        now = float(i)
        hl.on_feedback("t", True, now)
        if 2 <= i:
            hl.on_broadcast("r2", "t", 500.0, now)
        if 6 <= i:
            hl.on_broadcast("r3", "t", 500.0, now)
        states, _ = hl.tick(now)
        resets.append(states[0].resetted)
    assert [i for i, r in enumerate(resets) if r] == [2, 6]  # not once per process: once per robot


def test_suppression_one_active_set_at_a_time():
    hl = HighLevel("r1", robot(bset("a", theta=30.0, fast=10.0, giving_up=100, yielding=100),
                               bset("b", theta=40.0, fast=10.0, giving_up=100, yielding=100)))
    trace = run(hl, 0.0, 8)
    assert trace[2][0]["a"].active  # 3 ticks
    for st, _ in trace[3:]:
        assert st["a"].active and not st["b"].active
        assert st["b"].suppressed and st["b"].motivation == 0.0


def test_simultaneous_threshold_crossing_picks_one():
    hl = HighLevel("r1", robot(bset("a", theta=30.0, fast=10.0), bset("b", theta=20.0, fast=10.0)))
    trace = run(hl, 0.0, 3)
    # b crosses at tick 2 (20/20), a would at tick 3; b wins tick 2 then a is suppressed
    assert trace[1][0]["b"].active and not trace[2][0]["a"].active


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
