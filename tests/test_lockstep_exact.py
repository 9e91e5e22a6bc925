"""A busy machine must not change what a lockstep run does (a study's run must not fail
because the machine is busy): a slow participant — one that holds its token but takes longer
than REPORT_AFTER (2.5 s) to answer, as a CPU-starved agent does under load 30+ — is
reported and still waited for; only one silent for the whole timeout is given up, and then the
run says it was not exact (summary.json `lockstep_exact`), and `mrta experiment` runs it again.

In-process bus and a hand-moved wall clock: nothing here depends on the machine's speed."""

import contextlib
import logging
import threading
import time
import pytest

from mrta_zenoh import codec
from mrta_zenoh.bus.inproc import InProcBus, InProcNetwork
from mrta_zenoh.clock import run_id
from mrta_zenoh.keys import CLOCK_SOURCE_TOKEN
from mrta_zenoh.lockstep.barrier import Barrier
from mrta_zenoh.lockstep.participant import LockstepClock
from mrta_zenoh.lockstep.protocol import (DONE, REPORT_AFTER, STATUS, WORK_LIMIT, LockstepStatus,
                                          StepDone)
from mrta_zenoh.messages import Twist
from mrta_supervisor.experiment import api as experiment
from mrta_supervisor.mission.analysis import lockstep_trouble
from mrta_supervisor.mission.summary import MessageRates, Summary, write_summary
from tests.harness import helpers
from tests.harness.helpers import Wall


def wait_for(cond):
    """tests.harness.helpers.wait_for with room for a loaded machine's thread scheduling."""
    helpers.wait_for(cond, timeout=20.0, poll=0.005)


def in_thread(fn):
    done = threading.Event()

    def run():
        fn()
        done.set()
    threading.Thread(target=run, daemon=True).start()
    return done


class Cpu:
    """The participant's loop thread's CPU time, moved by hand (`cpu.t += 0.5`)."""

    def __init__(self):
        self.t = 0.0

    def follow(self, thread):
        pass

    def __call__(self):
        return self.t


@contextlib.contextmanager
def fleet(cpu=None):
    """A lockstep simulator's barrier (30 s timeout, a hand-moved wall clock) and one
    participant, robot1, on one in-process network; the statuses the barrier publishes."""
    net, wall, stop = InProcNetwork(), Wall(), threading.Event()
    sim_bus = InProcBus(net)
    run = run_id(0)
    sim_bus.subscribe("*/cmd_vel", lambda s: None, msg_type=Twist)
    barrier = Barrier(sim_bus, run, 30.0, wall=wall)
    statuses = []
    sim_bus.subscribe(STATUS, lambda s: statuses.append(s.message), msg_type=LockstepStatus)
    source = sim_bus.declare_token(f"{CLOCK_SOURCE_TOKEN}/{run}")
    clock = LockstepClock("robot1", wall=wall, cpu=cpu)
    stack = clock.join(InProcBus(net))
    try:
        wait_for(lambda: "robot1" in barrier.participants)
        yield barrier, clock, wall, stop, statuses
    finally:
        stop.set()
        stack.close()
        source.close()
        barrier.close()


def test_a_slow_participant_is_waited_for_and_a_hung_one_makes_the_run_inexact(caplog):
    caplog.set_level(logging.WARNING, logger="mrta.lockstep")
    with fleet() as (barrier, clock, wall, stop, statuses):
        barrier.publish(0.0)
        stepped = in_thread(lambda: barrier.wait(0.0, stop))
        wait_for(clock.started.is_set)           # the participant has step 0, and says nothing
        wait_for(lambda: barrier._stamp is not None)  # the barrier waits: its clock started
        wall.t += REPORT_AFTER + 1.0              # REPORT_AFTER (2.5 s) is long past
        wait_for(lambda: "still waited for" in caplog.text)
        assert not stepped.is_set() and barrier.unresponsive == set()
        answered = in_thread(lambda: clock.sleep_until(0.1, stop))  # it answers at last
        wait_for(stepped.is_set)
        assert barrier.given_up == 0 and barrier.forgiven == 0

        barrier.publish(0.1)
        stepped = in_thread(lambda: barrier.wait(0.1, stop))
        wait_for(answered.is_set)                 # it took step 0.1, then hangs (never answers)
        wait_for(lambda: barrier._stamp is not None)
        wall.t += 31.0                            # past the 30 s timeout, its token alive
        wait_for(stepped.is_set)
        assert barrier.unresponsive == {"robot1"} and barrier.given_up == 1
        wait_for(lambda: statuses and statuses[-1].given_up == 1)


def test_a_participant_still_computing_is_waited_for_past_the_timeout_a_stuck_one_is_not(caplog):
    """CBBA's first decision over a burst of 200 tasks costs each robot ≈ 2 CPU-s: at load 25
    that took 39 s of wall, past the 30 s timeout, and the run was given up as inexact. A
    participant whose loop thread uses CPU time says so (a work beat) and is waited for; one
    whose loop is stuck uses none, says nothing, and is given up after the timeout as before;
    one that beats for ever is given up after WORK_LIMIT timeouts."""
    caplog.set_level(logging.WARNING, logger="mrta.lockstep")
    cpu = Cpu()
    with fleet(cpu) as (barrier, clock, wall, stop, statuses):
        def computing(seconds):
            """The loop computes for `seconds` of wall, beating every 20 s of it."""
            for _ in range(int(seconds // 20)):
                cpu.t += 0.5
                beat = wall.t
                clock.beat()
                wait_for(lambda: barrier._working.get("robot1") == beat)
                wall.t += 20.0

        barrier.publish(0.0)
        stepped = in_thread(lambda: barrier.wait(0.0, stop))
        wait_for(clock.started.is_set)            # it took step 0 and computes its decision
        wait_for(lambda: barrier._stamp is not None)
        computing(100.0)                          # 100 s: more than three timeouts
        wait_for(lambda: "robot1 still computing t=0.00" in caplog.text)  # past the timeout
        assert not stepped.is_set() and not barrier.unresponsive
        answered = in_thread(lambda: clock.sleep_until(0.1, stop))  # done at last
        wait_for(stepped.is_set)
        assert barrier.given_up == 0              # the run stays exact

        barrier.publish(0.1)
        stepped = in_thread(lambda: barrier.wait(0.1, stop))
        wait_for(answered.is_set)                 # it took step 0.1, then its loop is stuck
        wait_for(lambda: barrier._stamp is not None)
        assert not clock.beat()                   # no CPU time used: no sign of work
        wall.t += 31.0
        wait_for(stepped.is_set)
        assert barrier.unresponsive == {"robot1"} and barrier.given_up == 1

    cpu = Cpu()
    with fleet(cpu) as (barrier, clock, wall, stop, statuses):
        barrier.publish(0.0)
        stepped = in_thread(lambda: barrier.wait(0.0, stop))
        wait_for(clock.started.is_set)
        wait_for(lambda: barrier._stamp is not None)
        caplog.clear()
        computing(WORK_LIMIT * 30.0 - 20.0)
        wait_for(lambda: "robot1 still computing t=0.00" in caplog.text)
        assert not stepped.is_set()
        computing(40.0)                           # past WORK_LIMIT timeouts, still beating
        wait_for(stepped.is_set)
        assert barrier.unresponsive == {"robot1"} and barrier.given_up == 1


def test_a_work_beat_is_no_answer_and_counts_only_from_the_participant_for_the_step():
    """A beat moves nothing (not the step, not the claims); one from a name without a token, or
    for another run or an earlier step, keeps nobody waited for."""
    with fleet(Cpu()) as (barrier, clock, wall, stop, statuses):
        barrier.publish(0.0)
        stepped = in_thread(lambda: barrier.wait(0.0, stop))
        wait_for(clock.started.is_set)
        wait_for(lambda: barrier._stamp is not None)
        beat = StepDone("robot1", 0.0, {"robot1/cmd_vel": 5}, -1.0, barrier.run, working=True)
        stranger = StepDone("robot9", 0.0, {}, -1.0, barrier.run, working=True)
        other_run = StepDone("robot1", 0.0, {}, -1.0, "another", working=True)
        bus = InProcBus(barrier.bus.network)
        for key, d in ((f"{DONE}/robot1", beat), (f"{DONE}/robot9", stranger),
                       (f"{DONE}/robot1", other_run)):
            bus.publish(key, d)
        wait_for(lambda: "robot1" in barrier._working)
        assert not stepped.is_set() and barrier.sent().get("robot1/cmd_vel") is None
        assert set(barrier._working) == {"robot1"}
        in_thread(lambda: clock.sleep_until(0.1, stop))
        wait_for(stepped.is_set)


def status_record(**kw):
    status = LockstepStatus(1.0, (), **kw)
    return (STATUS, codec.encoding_for(status.TYPE_NAME), 0, codec.encode(status))


def test_the_summary_reads_give_ups_and_forgiven_claims_from_the_recording():
    records = [status_record(), ("robot1/odom", "x", 0, b"\x00"),
               status_record(given_up=2, forgiven=1), (STATUS, "x", 0, b"not msgpack")]
    assert lockstep_trouble(records) == (2, 1)
    assert lockstep_trouble([status_record(dropped=5)]) == (0, 0)  # refused forgeries: exact
    assert lockstep_trouble([]) == (0, 0)


class Child:
    returncode = 0
    stdout: list[str] = []

    def running(self):
        return False

    def wait(self, timeout):
        return 0


def test_an_inexact_run_is_run_again_once_then_marked(tmp_path):
    out = tmp_path / "run000"
    out.mkdir()
    write_summary(out / "summary.json", Summary(
        mission="patrol", application="patrol", architecture="alliance", duration=10.0,
        speed=0.0, seed=1, wall_seconds=1.0, robots=["robot1"], who_did_what={},
        first_full_allocation=None, coverage={}, messages=MessageRates(1.0, 0.0, "alliance"),
        output=str(out), files=[], lockstep_exact=False, lockstep_given_up=1))
    run = experiment.Run(0, 1, "none", ())
    results = experiment.Results(tmp_path / "results.csv", 1)
    again = experiment._collect({0: (run, Child(), time.monotonic(), out)}, results, set())
    assert again == [run] and results.rows == []          # first time: run again, no row
    again = experiment._collect({0: (run, Child(), time.monotonic(), out)}, results, {0})
    assert again == [] and results.rows[0]["status"] == "inexact"
    assert "1 participant(s) given up" in results.rows[0]["error"]
    assert "inexact" in (tmp_path / "results.csv").read_text()


# ---------------------------------------------------------------- the order of what is heard

def alliance_agent(team=None):
    from pathlib import Path

    from mrta_agent.alliance.architecture import ALLIANCE
    from mrta_agent.runtime.host import AgentOptions
    from mrta_zenoh.clock import ManualClock
    config = Path(__file__).resolve().parent.parent / "configs/applications/patrol/config"
    prepared = ALLIANCE.prepare(AgentOptions("robot1", config / "robot1_alliance_params.yaml",
                                             config / "tasks_alliance_params.yaml"))
    bus, clock = InProcBus(), ManualClock(0.0)
    agent = ALLIANCE.agent(prepared, bus, clock)
    agent.limit_team(team)
    agent.start()
    return agent, bus, clock


@pytest.mark.slow
def test_in_lockstep_what_is_due_comes_in_time_sender_key_and_sequence_order():
    """Not in arrival order: the network picks that, even for one teammate's messages on two
    keys, and it changed which bid an injected loss drew (docs/delivery.md, Reproducibility)."""
    from mrta_agent.alliance.messages import InterRobotCommunication
    from mrta_zenoh.messages import Header
    agent, bus, clock = alliance_agent()
    clock.in_lockstep = lambda: True
    tokens = [bus.declare_token(f"{r}/alliance/agent") for r in ("robot2", "robot3")]
    key = "{}/alliance/inter_robot_communication"
    for sender, stamp, seq in (("robot3", 0.1, 1), ("robot2", 0.1, 2), ("robot3", 0.0, 1),
                               ("robot2", 0.1, 1)):
        bus.publish(key.format(sender), InterRobotCommunication(Header(sender, stamp, seq),
                                                                "wander", 10.0))
    due = agent.take_due(0.2)
    assert [(t, s, m.header.seq) for t, _, s, m, _ in due] == [
        (0.0, "robot3", 1), (0.1, "robot2", 1), (0.1, "robot2", 2), (0.1, "robot3", 1)]
    for t in tokens:
        t.close()
    agent.shutdown()


@pytest.mark.slow
def test_an_agent_in_lockstep_waits_for_its_roster_before_its_first_tick():
    agent, bus, clock = alliance_agent(team=("robot1", "robot2", "robot3"))
    stop = threading.Event()
    two = bus.declare_token("robot2/alliance/agent")
    assert agent.await_team(stop, limit=5.0) == []            # out of lockstep: no waiting
    clock.in_lockstep = lambda: True
    assert agent.await_team(stop, limit=0.05) == ["robot3"]   # bounded: says who is missing
    three = bus.declare_token("robot3/alliance/agent")
    assert agent.await_team(stop, limit=5.0) == []
    free, _, free_clock = alliance_agent()                    # no roster: nobody to wait for
    free_clock.in_lockstep = clock.in_lockstep
    assert free.await_team(stop, limit=5.0) == []
    for h in (two, three):
        h.close()
    agent.shutdown()
    free.shutdown()


def test_the_clock_and_lockstep_status_are_not_traffic():
    from mrta_agent.alliance.architecture import ALLIANCE
    from mrta_supervisor.mission.analysis import is_traffic, message_rates
    assert not is_traffic("clock") and not is_traffic(STATUS)
    assert not is_traffic("@liveliness/robot1/alliance/agent")
    assert is_traffic("robot1/odom") and is_traffic("robot1/alliance/inter_robot_communication")
    records = [("clock", "", 0.0, b""), (STATUS, "", 0.5, b""), ("robot1/odom", "", 0.5, b""),
               ("robot1/alliance/inter_robot_communication", "", 1.0, b""),
               ("robot1/odom", "", 2.0, b"")]             # the last instant: not counted
    rates = message_rates(records, ALLIANCE, 2.0, time_of=lambda t: t)
    assert rates.total_per_second == 1.0 and rates.coordination_per_second == 0.5


def test_what_a_participant_forgave_reaches_the_simulators_status():
    """An agent that forgave samples that never arrived (its own books) says so in every
    StepDone; the simulator adds it to `lockstep/status`, so the summary calls the run inexact
    — not only what the simulator itself forgave."""
    with fleet() as (barrier, clock, wall, stop, statuses):
        barrier.publish(0.0)
        stepped = in_thread(lambda: barrier.wait(0.0, stop))
        wait_for(clock.started.is_set)
        clock.forgiven = 3                     # as if its books had forgiven three claims
        in_thread(lambda: clock.sleep_until(0.1, stop))
        wait_for(stepped.is_set)
        wait_for(lambda: statuses and statuses[-1].forgiven == 3)
        assert barrier.given_up == 0


def test_a_participant_waits_for_its_own_samples_to_reach_its_own_subscriptions():
    """Zenoh hands a session's own samples to its subscribers on another thread: a robot's
    report heard back by its own ReportDue could reach it a tick apart in two runs of one seed.
    The books count what this bus sent on a key its own subscriptions count, as a claim."""
    from mrta_zenoh.lockstep.books import Books
    from mrta_zenoh.lockstep.table import Claims, KeyTable

    net = InProcNetwork()
    bus, other = InProcBus(net), InProcBus(net)
    bus.subscribe("*/patrol/report", lambda s: None)
    counts = bus.enable_counting()
    books, none = Books(counts), Claims(KeyTable(), [])  # a step that claims nothing
    assert books.missing(none) == {}
    counts.sent["robot3/patrol/report"] += 1  # sent, not yet heard back
    counts.sent["robot3/cmd_vel"] += 1        # sent, heard by no subscription of its own
    assert books.missing(none) == {"robot3/patrol/report": 1}
    other.publish("robot3/patrol/report", Twist(0.0, 0.0))  # now it has come back
    assert books.missing(none) == {}
    assert books.missing(none, ["robot3/patrol/report"]) == {}
    bus.close()
    other.close()


def test_the_clock_watchdog_stops_no_robot_while_lockstep_waits():
    """A robot's clock watchdog commands zero velocity when no clock sample came for 2 wall s
    (its simulator is gone), but not in lockstep: there time standing still is the protocol
    waiting for a slow participant, and a zero command sent at that wall instant stopped the
    robot for a step it would have driven — a live run and its summary's replay drifted by a
    tick or two wherever one of them was slow (issue 50, point 4)."""
    from types import SimpleNamespace

    from mrta_agent.runtime.host import CLOCK_WATCHDOG, watch_clock

    wall = Wall()
    clock = LockstepClock("robot1", wall=wall)
    clock.started.set()
    sent = []
    robot = SimpleNamespace(robot_id="robot1", is_process=False, log=logging.getLogger("t"),
                            ctx=SimpleNamespace(publish_cmd=lambda v, w: sent.append((v, w))))
    wall.t += CLOCK_WATCHDOG + 1.0
    clock.lockstep.set()  # a step taken: the simulator waits for someone
    assert watch_clock(lambda: (robot,), clock, False) is False and sent == []
    clock.lockstep.clear()  # its barrier token went: the simulator is gone
    assert watch_clock(lambda: (robot,), clock, False) is True and sent == [(0.0, 0.0)]
    assert watch_clock(lambda: (robot,), clock, True) is True and sent == [(0.0, 0.0)]  # once
