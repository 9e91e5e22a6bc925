"""Monitoring is not claimed in lockstep (Bus.leave_unclaimed): an ALLIANCE robot's motivation
and sensory feedback per task are for observers, so a step never waits for them and they do not
fill the run's key table — 100 robots with 100 tasks would have put 20,000 such keys into a
table that holds 4,096 (MAX_KEYS), and lockstep dropped most robots' claims."""

from __future__ import annotations

from mrta_agent.runtime.coordinator import Coordinator, Say
from mrta_agent.runtime.loop import Agent
from mrta_agent.runtime.plugins import Plugins
from mrta_zenoh.bus import InProcBus
from mrta_zenoh.clock import ManualClock
from mrta_zenoh.messages import Header
from mrta_zenoh.lockstep.participant import LockstepClock
from mrta_zenoh.lockstep.protocol import StepDone
from tests.harness.alliance_team import IRC, TASK, Spec, make_agent


def test_a_bus_claims_what_it_sent_less_the_keys_left_unclaimed():
    bus = InProcBus()
    counts = bus.enable_counting()
    for key in ("r1/a", "r1/a", "r1/b", "r1/c"):
        bus.publish(key, Header("r1", 0.0, 1))
    bus.leave_unclaimed("r1/b")
    assert counts.sent == {"r1/a": 2, "r1/b": 1, "r1/c": 1}  # still counted as sent
    assert counts.claims() == {"r1/a": 2, "r1/c": 1}


def test_an_alliance_robot_claims_its_broadcasts_but_not_its_monitoring():
    bus = InProcBus()
    counts = bus.enable_counting()
    clock = ManualClock(0.0)
    spec = Spec(spin=10.0, broadcast=5.0, tau=1.0, theta=1.0, fast=0.5, expected=10.0,
                yielding=100.0)
    agent = make_agent("robot1", spec, bus, clock)
    for tick in range(10):
        clock.set(tick / 10)
        agent.tick_high(tick / 10)
    assert agent.active_task == TASK  # active after ⌈θ/δ_fast⌉ = 2 ticks: it broadcasts
    motivation = f"robot1/alliance/motivation/{TASK}"
    feedback = "robot1/alliance/sensory_feedback"
    broadcast = f"robot1/alliance/{IRC}"
    assert counts.sent[motivation] == 10 and counts.sent[feedback] == 10
    claims = counts.claims()
    assert broadcast in claims and claims[broadcast] == counts.sent[broadcast] > 0
    assert motivation not in claims and feedback not in claims


def test_a_participants_answer_carries_only_the_claimed_keys():
    """What the simulator's barrier reads: the StepDone a participant publishes."""

    class Says(Coordinator):
        def tick(self, now):
            return [Say("inter_robot_communication",
                        dict(task_id="t", expected_duration=1.0, active_since=0.0)),
                    Say("motivation", dict(task_id="t", impatience=0.0, acquiescent=False,
                                           suppressed=False, resetted=False, applicable=True,
                                           motivation=0.0, threshold=1.0, active=False),
                        subkey="t", lossy=True, watched=True)]

    from mrta_agent.alliance.architecture import ALLIANCE
    bus = InProcBus()
    lockstep = LockstepClock("robot1")
    answers: list[StepDone] = []
    with lockstep.join(bus):
        bus.subscribe("@mrta/lockstep/done/*", lambda s: answers.append(s.message),
                      msg_type=StepDone)
        agent = Agent("robot1", ALLIANCE, Says, bus, ManualClock(0.0), None,
                      Plugins([], [], {}, None), 10.0, 10.0)
        agent.tick_high(0.0)
        lockstep._publish_done(0.0, 0.1)
    assert answers and answers[-1].sent == {"robot1/alliance/inter_robot_communication": 1}
