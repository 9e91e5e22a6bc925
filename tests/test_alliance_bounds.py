"""ALLIANCE's takeover bound, stated so it holds: τ + (⌈θ/δ_fast⌉ + 1)/ρ counted from the
taker's last reception of any broadcast on the task — not from the dead robot's last broadcast
as received, which a survivor that missed it while still hearing a robot that had just yielded
the task outlives (the yielded robot keeps its impatience slow for τ; computed by hand in
tests/test_alliance_corner_cases.py) — and the mission summary's instant, which the run's
recording gives exactly in lockstep."""

from __future__ import annotations

import dataclasses
import itertools
import math
import os
import threading

import numpy as np
import pytest
from hypothesis import HealthCheck, event, given, settings, strategies as st

from mrta_agent.alliance.architecture import ALLIANCE
from mrta_agent.alliance.messages import InterRobotCommunication
from mrta_agent.runtime.host import AgentOptions
from mrta_zenoh.architectures import Takeover
from mrta_zenoh.bus import InProcBus
from mrta_zenoh.clock import ManualClock
from mrta_zenoh.codec import encode, encoding_for
from mrta_zenoh.failure import parse_faults, plan_for
from mrta_zenoh.messages import Header
from tests.harness.alliance_fixtures import robot_yaml, tasks_yaml, write
from tests.harness.alliance_team import Network, Spec, Team

EXAMPLES = int(os.environ.get("MRTA_PROPERTY_EXAMPLES", "30"))  # more on demand
# ρ=10 Hz, τ=3, θ=21, δ_fast=1.5 → 14 ticks: bound 3 + (14 + 1)/10 = 4.5 s
CASE = Spec(spin=10.0, broadcast=1.0, tau=3.0, theta=21.0, fast=1.5, expected=600.0,
             yielding=1.0)


# ---------------------------------------------------------------- real agents, adversary
def cycle(values):
    """The adversary's choices, one per broadcast and receiver, in order, round and round."""
    it = itertools.cycle(values)
    return lambda sender, receiver, t: next(it)


def takeovers(team: Team, victim: str, kill_at: float, end: float) -> tuple[float, set[str]]:
    """(when, by whom) the task was next held after the death of its sole holder."""
    for t0, _, h in team.intervals(end):
        if t0 >= kill_at and h - {victim}:
            return t0, set(h - {victim})
    raise AssertionError(f"nobody took the task over between {kill_at} and {end}")


def check_bound_from_last_reception(team: Team, victim: str, kill_at: float, end: float):
    """Every robot that took the task over did so within its bound of its last reception of
    any broadcast on the task; returns (takeover time, the dead robot's last broadcast each
    taker heard) for the callers' own checks."""
    after, takers = takeovers(team, victim, kill_at, end)
    from_victim = {}
    for taker in takers:
        spec = team.robots[taker].spec
        last = team.last_heard(taker, after)
        if last is None:  # impatient from its start, as the summary counts from the fault
            last = spec.phase
        bound = spec.takeover_bound()
        assert after - last <= bound + 1e-9, (taker, after, last, bound)
        from_victim[taker] = max((t for t in team.arrivals.get((taker, victim), ())
                                  if t <= after), default=-math.inf)
    return after, from_victim


def test_real_agents_yield_then_the_holder_dies_and_a_survivor_misses_its_last_broadcast():
    """The case on the agents `mrta agent` runs: r2 is cut off until 20 s (so r1 and
    r2 both take the task); r2's first broadcast after the cut reaches r1 a second late, so
    r1 broadcasts once more before yielding to it; r2's next broadcast is lost to r3, and r2
    dies. r3 takes over more than the bound after r2's last broadcast it heard, and within
    the bound of r1's, the last on the task it heard."""
    specs = {"r1": CASE, "r2": dataclasses.replace(CASE, phase=0.05),
             "r3": dataclasses.replace(CASE, phase=0.02)}

    def delay(sender, receiver, t):
        return 1.0 if (sender, receiver) == ("r2", "r1") and 20.0 <= t < 21.0 else 0.005

    def lose(sender, receiver, t):
        return (sender, receiver) == ("r2", "r3") and t >= 21.0

    team = Team(specs, Network(delay=delay, lose=lose,
                               cuts=[(0.0, 20.0, frozenset({"r2"}))]), 0).run(21.5)
    assert team.holders() == {"r2"}  # r1 yielded to it
    team.kill("r2", 21.5)
    team.run(40.0)
    after, from_victim = check_bound_from_last_reception(team, "r2", 21.5, 40.0)
    bound = CASE.takeover_bound()
    assert "r3" in takeovers(team, "r2", 21.5, 40.0)[1]
    assert after - from_victim["r3"] > bound  # counted from the victim's last broadcast: over


@st.composite
def specs(draw) -> Spec:
    spin = draw(st.sampled_from([2.0, 4.0, 5.0, 10.0]))
    broadcast = draw(st.sampled_from([0.5, 1.0, 2.0]).filter(lambda b: b <= spin))
    period = math.ceil(round(spin / broadcast, 9)) / spin
    theta = draw(st.floats(10.0, 100.0))
    return Spec(spin=spin, broadcast=broadcast,
                tau=round(max(period * draw(st.floats(2.0, 4.0)), 1.5 / spin), 3),
                theta=theta, fast=theta / draw(st.integers(1, 25)),
                expected=draw(st.floats(30.0, 600.0)), yielding=draw(st.floats(0.2, 4.0)))


@st.composite
def handovers(draw):
    """Three or four robots; r2 cut off from the others until `heal`, so both sides take the
    task and, once they hear each other, the earlier yields. Every broadcast is delayed
    (0–1.5 s: reordered) and lost as the adversary says; when the holder dies, one robot
    (`deaf`) also loses whatever the holder still had on its way to it."""
    robots = draw(st.lists(specs(), min_size=3, max_size=4))
    names = [f"r{i + 1}" for i in range(len(robots))]
    team = {n: dataclasses.replace(s, phase=0.37 * i * s.tick)
            for i, (n, s) in enumerate(zip(names, robots))}
    heal = draw(st.floats(5.0, 15.0))
    delays = cycle(draw(st.lists(st.floats(0.0, 1.5), min_size=8, max_size=48)))
    losses = cycle(draw(st.lists(st.sampled_from([False] * 4 + [True]), min_size=8,
                                 max_size=48)))
    net = Network(delay=delays, lose=losses, cuts=[(0.0, heal, frozenset({"r2"}))])
    kill_after = draw(st.one_of(st.just(0.0), st.floats(0.0, 1.5)))  # after the yield
    deaf = draw(st.sampled_from(names))  # misses what the holder still has on its way
    return team, net, heal, kill_after, deaf, draw(st.integers(0, 2**31 - 1))


@pytest.mark.slow  # a property at its full count; the witnesses above stay in the fast tier
@settings(max_examples=EXAMPLES, derandomize=True, deadline=None,
          suppress_health_check=[HealthCheck.too_slow])
@given(handovers())
def test_the_bound_holds_from_the_takers_last_reception_under_any_delivery_order(case):
    """At the heal the earlier holder yields; the holder left dies a little later, while
    broadcasts are reordered and lost. Whoever takes the task over does so within its bound
    of its last reception of any broadcast on the task."""
    team_specs, net, heal, kill_after, deaf, seed = case
    team = Team(team_specs, net, seed)
    t = heal
    for wait in (0.05, 0.25):  # till one holder is left (a yield), and again after the pause
        while len(team.run(t).holders()) != 1 and t < heal + 20.0:
            t += wait
        t += kill_after if wait == 0.05 else 0.0
    if len(team.run(t).holders()) != 1:
        event("two holders throughout: nothing to take over")
        return
    (victim,) = team.holders()
    team.kill(victim, t)
    if deaf != victim:
        team.drop_in_flight(victim, deaf)
    end = t + max(s.takeover_bound() for s in team_specs.values()) + 2 * 1.5 + 1.0
    team.run(end)
    after, from_victim = check_bound_from_last_reception(team, victim, t, end)
    # what the examples covered (pytest --hypothesis-show-statistics)
    later = [r for r, v in from_victim.items() if (team.last_heard(r, after) or -math.inf) > v]
    event("the taker heard another robot after the dead one's last broadcast" if later
          else "the dead robot's broadcast was the last the taker heard")
    if any(after - from_victim[r] > team.robots[r].spec.takeover_bound() for r in later):
        event("from the dead robot's last broadcast heard, the bound fails")


# ---------------------------------------------------------------- the summary's instant
def test_the_summarys_instant_is_the_last_broadcast_the_takers_agent_heard(tmp_path):
    """In lockstep with loss and latency: at every instant, the one ALLIANCE.takeover_check
    reads from the recording (re-drawing the run's seeded faults) is the last reception of a
    broadcast on the task robot3's own agent had made, under the same faults, by then."""
    rf = write(tmp_path / "robot3.yaml", robot_yaml([{"task": "t", "theta": 21.0,
                                                      "fast": 1.5}], spin=10.0, tau=3.0))
    tf = write(tmp_path / "tasks.yaml", tasks_yaml(["t", "u"]))
    bus, clock = InProcBus(), ManualClock(0.0)
    clock.lockstep = threading.Event()
    clock.lockstep.set()
    agent = ALLIANCE.agent(ALLIANCE.prepare(AgentOptions("robot3", rf, tf)), bus, clock,
                           np.random.default_rng(1))
    faults = parse_faults("loss:0.3,latency:0.4±0.3")
    agent.faults = plan_for(faults, "robot3", 7)
    agent.start()
    for r in ("robot1", "robot2"):
        bus.declare_token(ALLIANCE.agent_token(r))
    records, known = [], {}
    rng = np.random.default_rng(3)
    seq = {"robot1": 0, "robot2": 0}
    for k in range(120):
        now = k / 10
        clock.set(now)
        agent.tick_high(now)  # handles what it heard before now (lockstep)
        heard = agent.coordinator.high.sets["t"].others
        if heard:
            known[now] = max(r.last_heard for r in heard.values())
        for sender in ("robot1", "robot2"):
            if rng.random() < 0.3:  # each robot broadcasts now and then, on t or on u
                seq[sender] += 1
                task = "t" if rng.random() < 0.7 else "u"
                msg = InterRobotCommunication(Header(sender, now, seq[sender]), task, 600.0,
                                              0.0 if sender == "robot1" else 3.0)
                key = ALLIANCE.key(sender, "inter_robot_communication")
                bus.publish(key, msg)
                records.append((key, encoding_for(msg.TYPE_NAME), k, encode(msg)))
    assert agent.injector.dropped > 5  # the loss took some
    for now, last in known.items():
        got = ALLIANCE.takeover_check(Takeover(
            "t", "robot2", 5.0, "robot3", now - 1e-9, rf, records, lambda t: t / 10, faults, 7,
            True))
        assert got.since == pytest.approx(last), now
        assert got.seconds == pytest.approx(4.5)
    sender = next(n for n, r in heard.items() if r.last_heard == last)
    assert got.since_what.startswith(f"{sender}'s broadcast heard at {last:.2f} s")
