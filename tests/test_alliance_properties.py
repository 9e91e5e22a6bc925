"""ALLIANCE's guarantees as properties, on virtual time (tests/harness/alliance_team.py): random valid
parameters, random start phases (or identical robots in phase), latency, jitter up to half the
broadcast period, loss, deaths and partitions. Each invariant carries its bound.

CI runs a fixed seed and a bounded number of examples; `MRTA_PROPERTY_EXAMPLES=2000 pytest
tests/test_alliance_properties.py` runs more on demand. Marked `slow`: the full run's, not the
fast tier's (pyproject.toml).
"""

from __future__ import annotations

import dataclasses
import math
import os

import pytest
from hypothesis import HealthCheck, given, settings, strategies as st

from tests.harness.alliance_team import Network, Spec, Team

pytestmark = pytest.mark.slow  # 20 s of CPU at these example counts: not in the fast tier

EXAMPLES = int(os.environ.get("MRTA_PROPERTY_EXAMPLES", "30"))
SETTINGS = settings(max_examples=EXAMPLES, derandomize=True, deadline=None,
                    suppress_health_check=[HealthCheck.too_slow])
DURATION = 150.0


@st.composite
def specs(draw) -> Spec:
    spin = draw(st.sampled_from([1.0, 2.0, 2.5, 4.0, 5.0, 10.0]))
    broadcast = draw(st.sampled_from([0.25, 0.5, 1.0, 2.0, 5.0]).filter(lambda b: b <= spin))
    period = math.ceil(round(spin / broadcast, 9)) / spin  # broadcasts leave on ticks
    tau = max(period * draw(st.floats(2.0, 4.0)), 1.5 / spin)
    theta = draw(st.floats(10.0, 100.0))
    ticks_to_activate = draw(st.integers(1, 25))
    return Spec(spin=spin, broadcast=broadcast, tau=round(tau, 3), theta=theta,
                fast=theta / ticks_to_activate, expected=draw(st.floats(10.0, 80.0)),
                yielding=draw(st.floats(0.5, 8.0)))


@st.composite
def teams(draw, loss: bool = False):
    n = draw(st.integers(2, 5))
    in_phase = draw(st.booleans())
    base = draw(specs())
    team = {}
    for i in range(n):
        s = base if in_phase else draw(specs())
        phase = 0.0 if in_phase else draw(st.floats(0.0, s.tick * 0.999))
        team[f"r{i + 1}"] = dataclasses.replace(s, phase=phase)
    min_period = min(math.ceil(round(s.spin / s.broadcast, 9)) / s.spin for s in team.values())
    net = Network(latency=draw(st.floats(0.0, 0.02)),
                  jitter=draw(st.floats(0.0, 0.5)) * min_period,  # up to half a period
                  loss=draw(st.floats(0.0, 0.2)) if loss else 0.0)
    return team, net, draw(st.integers(0, 2**31 - 1))


def first_activation(team: Team) -> float:
    return next(t for t, h in team.timeline if h)


def overlaps(team: Team, end: float) -> list[tuple[str, str, float, float]]:
    """(a, b, start, end) of every maximal stretch with both a and b holding the task."""
    out, since = [], {}
    for t0, _, holders in team.intervals(end) + [(end, end, frozenset())]:
        pairs = {(a, b) for a in holders for b in holders if a < b}
        for pair in [p for p in since if p not in pairs]:
            out.append((*pair, since.pop(pair), t0))
        for pair in pairs:
            since.setdefault(pair, t0)
    return out


def check_overlaps(team: Team, end: float) -> None:
    """No single-robot task is held by two robots for longer than ψ + τ + one tick once both
    hear each other (overlaps during which a broadcast between them was lost are skipped)."""
    specs = {n: r.spec for n, r in team.robots.items()}
    for a, b, t0, t1 in overlaps(team, end):
        if t1 >= end or team.lost_between(a, b, t0, t1):
            continue
        heard = max(team.first_heard(a, b, t0), team.first_heard(b, a, t0))
        bound = max(specs[a].yielding, specs[b].yielding) + \
            max(specs[a].tau, specs[b].tau) + max(specs[a].tick, specs[b].tick)
        assert t1 - heard <= bound + 1e-6, (a, b, t0, heard, t1, bound)


def activation_bound(team: Team, duration: float, disturbances: int) -> int:
    """No livelock: a robot takes the task over at most once per φ (its holder's expected
    duration) and once per disturbance; identical robots in phase converge at once."""
    n = len(team.robots)
    phi = min(r.spec.expected for r in team.robots.values())
    return n * (2 + disturbances) + int(n * duration / phi)


@SETTINGS
@given(teams())
def test_a_healthy_team_keeps_the_task_held_by_one_robot(case):
    specs, net, seed = case
    team = Team(specs, net, seed).run(DURATION)
    assert sum(team.activations.values()) <= activation_bound(team, DURATION, 0)  # no livelock
    start = first_activation(team)
    assert start <= max(s.phase + s.takeover_bound() for s in specs.values())
    assert team.uncovered(start, DURATION) == 0.0  # once held, never dropped
    check_overlaps(team, DURATION)
    # jitter up to half the broadcast period never resets anybody: every reset is one new
    # activation of another robot
    for name, resets in team.resets.items():
        assert resets <= sum(a for n, a in team.activations.items() if n != name)


@SETTINGS
@given(teams(), st.floats(30.0, 100.0))
def test_takeover_after_a_death_within_the_bound(case, kill_at):
    specs, net, seed = case
    team = Team(specs, net, seed).run(kill_at)
    while len(team.holders()) != 1:  # the sole holder dies (not one of two mid-handover)
        kill_at += 0.5
        team.run(kill_at)
    (victim,) = team.holders()
    team.kill(victim, kill_at)
    team.run(DURATION + kill_at)
    survivors = [s for n, s in specs.items() if n != victim]
    bound = min(s.takeover_bound() for s in survivors) + net.latency + net.jitter + \
        max(s.tick for s in survivors)
    after = next(t0 for t0, t1, h in team.intervals(DURATION + kill_at)
                 if t1 > t0 >= kill_at and h - {victim})  # a stretch with a live holder
    assert after - kill_at <= bound + 1e-6, (after - kill_at, bound)
    assert team.uncovered(after, DURATION + kill_at) == 0.0


@SETTINGS
@given(teams(), st.floats(20.0, 60.0), st.floats(1.0, 30.0))
def test_a_partition_heals_without_a_gap(case, cut_at, extra):
    specs, net, seed = case
    team = Team(specs, net, seed).run(cut_at)
    holder = sorted(team.holders())[:1]
    if not holder:
        return
    tau = max(s.tau for s in specs.values())
    heal = cut_at + tau + extra  # longer than τ: the others take over meanwhile
    net.cuts.append((cut_at, heal, frozenset(holder)))
    team.run(DURATION + heal)
    start = first_activation(team)
    assert team.uncovered(start, DURATION + heal) == 0.0  # no gap, during or after
    check_overlaps(team, DURATION + heal)
    # the holder cut off keeps working (it does not know); somebody took over on the other
    # side unless the cut-off robot was alone with nobody able to hear: both hold at the heal
    assert sum(team.activations.values()) <= activation_bound(team, DURATION + heal, 2)


@SETTINGS
@given(teams(loss=True))
def test_with_lost_broadcasts_the_task_stays_held_and_there_is_no_livelock(case):
    specs, net, seed = case
    team = Team(specs, net, seed).run(DURATION)
    start = first_activation(team)
    assert team.uncovered(start, DURATION) == 0.0
    lossy = int(DURATION * len(specs) * net.loss / min(s.tau for s in specs.values())) + 1
    assert sum(team.activations.values()) <= activation_bound(team, DURATION, lossy)
