"""Lockstep for an agent host: one participant answering for several robots (SPEAKS tokens).
The barrier takes its claims under those robots' names, caps them per robot, forgets them with
the token, and counts the robots as joined; a participant with no such token still claims under
its own name only. Pure logic and the in-process bus with a hand-moved wall clock."""

import threading

from mrta_zenoh.bus.inproc import InProcBus, InProcNetwork
from mrta_zenoh.clock import run_id
from mrta_zenoh.keys import CLOCK_SOURCE_TOKEN
from mrta_zenoh.lockstep.barrier import Barrier
from mrta_zenoh.lockstep.participant import LockstepClock
from mrta_zenoh.lockstep.protocol import CLAIM_KEYS, DONE, MAX_SPEAKS_FOR, StepDone
from mrta_zenoh.lockstep.ledger import Ledger
from mrta_zenoh.messages import Twist
from tests.harness.helpers import Wall, wait_for


def test_a_participant_claims_under_the_robots_it_speaks_for_only():
    ledger = Ledger()
    claims = {"host1/x": 1, "robot2/cmd_vel": 3}
    assert "robot2/cmd_vel" in ledger.over_cap("host1", claims, set())
    assert ledger.speaks_for("host1", "robot2", True)
    assert ledger.over_cap("host1", claims, set()) is None
    assert "robot3/cmd_vel" in ledger.over_cap("host1", {"robot3/cmd_vel": 1}, set())
    assert "robot2" in ledger.over_cap("host1", {"robot2": 1}, set())  # a bare name is no key
    assert ledger.speaks_for("host1", "robot2", False)
    assert ledger.over_cap("host1", claims, set()) is not None
    assert ledger.voices == {}


def test_caps_grow_with_the_robots_a_host_speaks_for_and_are_bounded():
    ledger = Ledger()
    many = {f"host1/k{i}": 1 for i in range(CLAIM_KEYS + 1)}
    assert ledger.over_cap("host1", many, set()) is not None
    ledger.speaks_for("host1", "robot2", True)
    assert ledger.over_cap("host1", many, set()) is None
    for i in range(MAX_SPEAKS_FOR - 1):
        assert ledger.speaks_for("host1", f"r{i}", True)
    assert not ledger.speaks_for("host1", "one-too-many", True)
    assert len(ledger.voices["host1"]) == MAX_SPEAKS_FOR


def test_a_host_takes_part_for_its_robots_and_their_commands_are_waited_for():
    net, wall = InProcNetwork(), Wall()
    sim_bus = InProcBus(net)
    run = run_id(0)
    received = []
    sim_bus.subscribe("*/cmd_vel", lambda s: received.append(s.key), msg_type=Twist)
    barrier = Barrier(sim_bus, run, 2.5, wall=wall)
    source = sim_bus.declare_token(f"{CLOCK_SOURCE_TOKEN}/{run}")
    host_bus, lone_bus = InProcBus(net), InProcBus(net)
    host = LockstepClock("host1", wall=wall, speaks_for=("robot1", "robot2", "host1"))
    lone = LockstepClock("robot3", wall=wall)
    stacks = [host.join(host_bus), lone.join(lone_bus)]
    stop = threading.Event()
    try:
        assert host.speaks_for == ("robot1", "robot2")  # itself needs no token
        wait_for(lambda: barrier.voiced() == {"host1", "robot1", "robot2", "robot3"})
        assert barrier.ledger.voices == {"host1": {"robot1", "robot2"}}
        barrier.publish(0.0)
        wait_for(lambda: host.now() == 0.0 and host.started.is_set())
        host_bus.publish("robot2/cmd_vel", Twist(0.1, 0.0))
        host_bus.publish("robot1/cmd_vel", Twist(0.1, 0.0))
        lone_bus.publish("robot2/cmd_vel", Twist(0.1, 0.0))  # robot3 speaks for nobody
        dropped = barrier.dropped.count
        host_bus.publish(f"{DONE}/host1", StepDone("host1", 0.0, host.counts.claims(), 0.1, run))
        lone_bus.publish(f"{DONE}/robot3", StepDone("robot3", 0.0, lone.counts.claims(), 0.1,
                                                    run))
        wait_for(lambda: "host1" in barrier.done and "robot3" in barrier.done)
        assert barrier.done["host1"].sent == {"robot2/cmd_vel": 1, "robot1/cmd_vel": 1}
        assert barrier.done["robot3"].sent == {}  # its claim under robot2 was dropped
        assert barrier.dropped.count == dropped + 1
        assert barrier.sent()["robot2/cmd_vel"] == 1
        barrier.wait(0.0, stop)
        stacks.pop(0).close()  # the host leaves: its robots with it
        wait_for(lambda: barrier.voiced() == {"robot3"})
        assert "host1" not in barrier.done and barrier.ledger.voices == {}
    finally:
        stop.set()
        for s in stacks:
            s.close()
        source.close()
        barrier.close()
