"""The agent's fault injector alone (robot_agent/runtime/faults.py), on the in-process bus and
a manual clock: each hook the driver calls does what the fault says, and counts it as the
robot's tally says it. The driver calling these hooks is tested in test_fault_injection.py."""

import logging

import pytest

from mrta_agent.alliance.messages import InterRobotCommunication
from mrta_agent.runtime.faults import FaultInjector
from mrta_agent.runtime.inbox import Heard, Inbox
from mrta_zenoh import keys
from mrta_zenoh.bus import InProcBus
from mrta_zenoh.clock import ManualClock
from mrta_zenoh.failure import FaultKind, parse_faults, plan_for
from mrta_zenoh.fault_roles import Assigned, assigned_key
from mrta_zenoh.fault_tally import EVERY_TALLY, TALLY_PERIOD, Cause
from mrta_zenoh.messages import Header, Odometry, Pose2D, Twist

KEY = "robot2/alliance/inter_robot_communication"


def injector(spec: str | None, robot: str = "robot1", seed: int = 3, lockstep: bool = True,
             roster=None):
    bus, clock = InProcBus(), ManualClock(0.0)
    clock.in_lockstep = lambda: lockstep
    inj = FaultInjector(robot, bus, clock, logging.getLogger("test"))
    inj.give(None if spec is None else plan_for(parse_faults(spec), robot, seed))
    handles = inj.listen(lambda: roster)
    tallies = []
    bus.subscribe(EVERY_TALLY, tallies.append)
    return inj, bus, clock, handles, tallies


def test_without_a_plan_every_hook_is_a_no_op():
    inj, bus, clock, handles, tallies = injector(None)
    assert handles == [] and inj.plan is None and not inj.delayed
    assert inj.on_receipt(KEY, 1, "robot2", 2.5) == 2.5
    assert inj.strikes(100.0) is None and not inj.cut("robot2", 1.0, 1.0)
    inj.heard_late(KEY, 1)
    inj.announce(1.0, "a")
    inj.tally(10.0)
    inj.final_tally()
    assert inj.dropped == 0 and not inj.counts and tallies == []


def test_loss_drops_the_seeded_messages_and_counts_them_once_due():
    inj, bus, clock, _, tallies = injector("loss:0.3")
    plan = inj.plan
    lost = [seq for seq in range(1, 201) if plan.lost(KEY, seq)]
    assert 30 < len(lost) < 90  # the seeded draw (failure.py), not the injector's own
    kept = [seq for seq in range(1, 201)
            if inj.on_receipt(KEY, seq, "robot2", seq / 100) is not None]
    assert sorted(kept + lost) == list(range(1, 201))
    # in lockstep a drop counts when it would have been heard: stamped before now
    inj.tally(1.0)
    assert tallies[-1].message.lost == sum(1 for s in lost if s / 100 < 1.0)
    inj.tally(1.0 + TALLY_PERIOD / 2)  # within the period: nothing new said
    assert len(tallies) == 1
    clock.set(2.5)
    inj.final_tally()  # as it stops: at once, whatever the period
    assert tallies[-1].message.lost == len(lost) == inj.dropped
    assert len(tallies) == 2 and tallies[-1].key == "robot1/faults/tally"


def test_latency_delays_the_time_heard_and_is_counted_when_handled():
    inj, bus, clock, _, tallies = injector("latency:0.4±0.3")
    assert inj.delayed
    heard = [inj.on_receipt(KEY, seq, "robot2", 1.0) for seq in range(1, 51)]
    assert all(0.1 <= h - 1.0 <= 0.7 for h in heard) and len(set(heard)) > 40
    assert heard == [1.0 + inj.plan.delay(KEY, seq) for seq in range(1, 51)]
    for seq in range(1, 51):
        inj.heard_late(KEY, seq)
    assert inj.counts[Cause.DELAYED] == 50 and inj.dropped == 0  # heard late, and heard
    inj.tally(2.0)
    assert (tallies[-1].message.delayed, tallies[-1].message.lost) == (50, 0)


def test_an_inbox_holds_a_delayed_message_until_its_time_and_orders_what_is_due():
    inj, *_ = injector("latency:0.4±0.3", lockstep=False)
    inbox = Inbox(size=3)
    for seq, t in ((1, 0.5), (2, 0.2), (3, 0.9), (4, 0.1)):  # the oldest goes: bounded
        inbox.put(Heard(t, "irc", "robot2", InterRobotCommunication(Header("robot2", 0.0, seq),
                                                                    "a", 60.0), KEY))
    assert len(inbox) == 3
    due = inbox.take_due(0.6, lockstep=False, delayed=inj.delayed)
    assert [item.message.header.seq for item in due] == [4, 2] and len(inbox) == 1
    assert [item.at for item in inbox.take_due(1.0, False, True)] == [0.9]


def test_a_partition_cuts_what_it_hears_and_what_its_peers_hear_from_it():
    inj, *_ = injector("partition:robot1@2+3")
    assert inj.on_receipt(KEY, 1, "robot2", 1.9) == 1.9
    assert inj.on_receipt(KEY, 2, "robot2", 2.0) is None  # robot1 hears nothing in [2, 5)
    assert inj.on_receipt(KEY, 3, "robot2", 5.0) == 5.0
    peer, *_ = injector("partition:robot2@2+3")  # robot1 drops what robot2 sends then
    assert peer.on_receipt(KEY, 2, "robot2", 3.0) == 3.0  # not on receipt: at the tick
    assert peer.cut("robot2", 3.0, 3.0) and not peer.cut("robot2", 5.0, 5.0)
    assert not peer.cut("robot3", 3.0, 3.0)
    assert (inj.dropped, peer.counts[Cause.CUT_OFF]) == (1, 1)


@pytest.mark.parametrize("spec,kind", [("robot1@4", FaultKind.CRASH),
                                       ("stall:robot1@4", FaultKind.STALL)])
def test_a_crash_or_a_stall_strikes_at_its_time(spec, kind):
    inj, *_ = injector(spec)
    assert inj.strikes(3.9) is None
    assert inj.strikes(4.0) is kind and inj.strikes(9.0) is kind
    other, *_ = injector(spec, robot="robot2")
    assert other.plan is None or other.strikes(9.0) is None


def _truth(bus, robot, x, stamp=0.0):
    bus.publish(keys.ground_truth(robot), Odometry(Header(robot, stamp, 0), Pose2D(x, 0.0, 0.0),
                                                   Twist(0.0, 0.0)))


def test_range_drops_a_teammate_farther_than_r_as_ground_truth_says():
    inj, bus, *_ = injector("range:8", lockstep=False)
    assert inj.on_receipt(KEY, 1, "robot2", 1.0) == 1.0  # positions unknown: in range
    _truth(bus, "robot1", 0.0)
    _truth(bus, "robot2", 5.0)
    assert inj.on_receipt(KEY, 2, "robot2", 1.0) == 1.0
    _truth(bus, "robot2", 9.0)
    assert inj.on_receipt(KEY, 3, "robot2", 1.0) is None
    assert inj.dropped == 1 and inj.counts[Cause.OUT_OF_RANGE] == 1


def test_in_lockstep_the_range_is_judged_at_the_tick_where_both_were_at_the_stamp():
    """A teammate's message may arrive before the simulator's ground truths of its own step
    (another process's link); judged at the tick, by then they are in, and a message is judged
    by the truths stamped no later than it — whatever arrived first (issue 47's identity)."""
    inj, bus, *_ = injector("range:8")
    _truth(bus, "robot1", 0.0, 0.9)
    _truth(bus, "robot2", 5.0, 0.9)
    assert inj.on_receipt(KEY, 1, "robot2", 1.0) == 1.0  # not judged on receipt in lockstep
    _truth(bus, "robot2", 9.0, 1.0)  # its step's truth, after the message
    _truth(bus, "robot2", 1.0, 1.1)  # a later step's: not where it was when it spoke
    assert inj.cut("robot2", 1.0, 1.0)
    assert not inj.cut("robot2", 0.95, 0.95)  # said at 0.95: it was at 5 then
    assert inj.dropped == 1 and inj.counts[Cause.OUT_OF_RANGE] == 1


def test_first_is_resolved_at_its_time_from_the_announcements_on_the_roster_only():
    inj, bus, clock, handles, _ = injector("stall:@first@2", roster=frozenset({"robot1",
                                                                               "robot2"}))
    said = []
    bus.subscribe(assigned_key("robot1"), said.append)

    def announce(robot, at, frame=None):
        bus.publish(assigned_key(robot), Assigned(Header(frame or robot, at, 1), "b"))
    announce("robot9", 0.1)  # off the roster
    announce("robot2", 0.2, frame="robot3")  # its key and header disagree
    inj.announce(0.5, None)  # no task yet: nothing said
    inj.announce(0.6, "a")
    inj.announce(0.7, "b")  # said once
    assert [s.message.header.stamp for s in said] == [0.6]
    assert inj.strikes(1.9) is None and inj.plan.first is not None
    assert inj.strikes(2.0) is FaultKind.STALL and inj.plan.first is None  # robot1 was first
    inj.restart()  # a new run: resolved again, announced again
    assert inj.plan.first is not None and inj.counts == {}
    announce("robot2", 0.1)
    assert inj.strikes(2.0) is None and inj.plan.first is None  # robot2 was first this time
    inj.announce(0.5, "a")
    assert len(said) == 2
    for h in handles:
        h.close()


def test_an_at_first_partition_of_a_teammate_becomes_a_peer_cut():
    inj, bus, *_ = injector("partition:@first@2+3")
    bus.publish(assigned_key("robot2"), Assigned(Header("robot2", 0.5, 1), "b"))
    assert not inj.cut("robot2", 2.5, 2.5)  # not resolved before its time
    assert inj.strikes(2.0) is None
    assert inj.cut("robot2", 2.5, 2.5) and not inj.cut("robot2", 1.5, 1.5)
    assert inj.on_receipt(KEY, 1, "robot2", 2.5) == 2.5  # robot1 itself is not cut off


def test_what_arrived_before_an_at_first_partition_struck_this_robot_is_cut_at_the_tick():
    """A teammate's message stamped at the fault's time may arrive before the loop resolves
    `@first`: on receipt it passes, at the tick it is cut — as if it had arrived after."""
    inj, bus, *_ = injector("partition:@first@2+3")
    inj.announce(0.5, "a")  # robot1 is first
    early = inj.on_receipt(KEY, 1, "robot2", 2.0)  # the network thread, before the loop
    assert early == 2.0 and inj.dropped == 0
    assert inj.strikes(2.0) is None and inj.plan.partitions == ((2.0, 5.0),)
    assert inj.on_receipt(KEY, 2, "robot2", 2.0) is None  # after: dropped on receipt
    assert inj.cut("robot2", 2.0, early) and not inj.cut("robot2", 1.9, 1.9)
    assert inj.dropped == 2 and inj.counts[Cause.CUT_OFF] == 2
