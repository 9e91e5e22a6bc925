"""Lockstep and the clock trust only their source: the pure logic on the
in-process bus, with a hand-moved wall clock. Each test is one attack or fault an independent
probe measured on a real fleet; tests/process/test_lockstep_attacks.py replays them with processes."""

import threading
import time
import pytest

from hypothesis import given, settings
from hypothesis import strategies as st

from mrta_zenoh.bus.inproc import InProcBus, InProcNetwork
from mrta_zenoh.clock import CEILING, RATE_MARGIN, SimClock, run_id, run_rate, run_speed
from mrta_zenoh.keys import CLOCK_SOURCE_TOKEN
from mrta_zenoh.lockstep.barrier import Barrier
from mrta_zenoh.lockstep.participant import LockstepClock
from mrta_zenoh.lockstep.protocol import (DONE, NEXT_HORIZON, PARTICIPANT, STEP, Step, StepDone,
                                          count_wait)
from mrta_zenoh.messages import Twist
from tests.harness.helpers import Wall, claiming_step, wait_for



class Fleet:
    """A lockstep simulator's barrier and one participant whose main loop ticks at 10 Hz and
    publishes a command per tick, on one in-process network; a forger's bus beside them."""

    def __init__(self, speed=2.0, timeout=2.5, members=None):
        self.net = InProcNetwork()
        self.wall = Wall()
        self.sim_bus = InProcBus(self.net)
        self.run = run_id(speed)
        self.sim_bus.subscribe("*/cmd_vel", lambda s: None, msg_type=Twist)
        self.barrier = Barrier(self.sim_bus, self.run, timeout, wall=self.wall,
                               members=members)
        self.source = self.sim_bus.declare_token(f"{CLOCK_SOURCE_TOKEN}/{self.run}")
        self.agent_bus = InProcBus(self.net)
        self.clock = LockstepClock("robot1", wall=self.wall)
        self.stack = self.clock.join(self.agent_bus)
        self.forger = InProcBus(self.net)
        self.stop = threading.Event()
        self.ticks = []
        self.extra = []
        self.thread = threading.Thread(target=self._loop, daemon=True)
        self.thread.start()
        self.threads = [self.thread]
        self.sim_time = 0.0
        self.barrier.publish(0.0)
        self.barrier.wait(0.0, self.stop)

    def _loop(self, clock=None, bus=None, name="robot1", ticks=None):
        clock, bus = clock or self.clock, bus or self.agent_bus
        ticks = self.ticks if ticks is None else ticks
        while not self.stop.is_set() and not clock.started.wait(0.01):
            pass
        epoch = clock.restarts
        t = clock.now()
        while not self.stop.is_set():
            if clock.restarts != epoch:
                epoch, t = clock.restarts, clock.now()
            ticks.append(clock.now())
            bus.publish(f"{name}/cmd_vel", Twist(0.1, 0.0))
            t += 0.1
            if t <= clock.now() + 1e-9:  # fell behind (it was stopped): skip, no burst
                t = clock.now() + 0.1
            if not clock.sleep_until(round(t, 6), self.stop):
                return

    def newcomer(self, name):
        """A second participant joining now, ticking as the first does; its clock."""
        bus = InProcBus(self.net)
        clock = LockstepClock(name, wall=self.wall)
        self.extra.append((clock.join(bus), bus))
        thread = threading.Thread(target=self._loop, args=(clock, bus, name, []), daemon=True)
        thread.start()
        self.threads.append(thread)
        return clock

    def advance(self, until):
        """The simulator's loop: 20 ms steps, stopping where the participant is due."""
        while self.sim_time < until - 1e-9:
            self.sim_time = round(self.sim_time + 0.02, 6)
            if self.barrier.due(self.sim_time):
                self.barrier.publish(self.sim_time)
                self.barrier.wait(self.sim_time, self.stop)

    def close(self):
        self.stop.set()
        for thread in self.threads:
            thread.join(2)
        for stack, bus in self.extra:
            stack.close()
            bus.close()
        self.stack.close()
        self.barrier.close()


def forged_step(fleet, stamp, step=10**6, run=None, sent=None):
    fleet.forger.publish(STEP, claiming_step(stamp, step, sent or {}, run or fleet.run,
                                             table=fleet.barrier.table))


def test_a_run_id_names_its_speed_and_bounds_its_rate():
    assert run_speed(run_id(2)) == 2.0 and run_speed(run_id(0)) == 0.0
    assert run_speed("run-a") is None and run_speed("x-xnan") is None
    assert run_rate(run_id(2)) == 2 * RATE_MARGIN and run_rate(run_id(0)) == CEILING
    assert run_rate("tokenless") is None


def test_one_forged_step_far_ahead_does_not_move_time():
    f = Fleet()
    try:
        f.advance(1.0)
        wait_for(lambda: f.clock.now() == 1.0)
        forged_step(f, 1e9)                       # the probe's forged step, with the real run id
        forged_step(f, 1e9, run="forger-x2")      # and from a run holding no barrier token
        assert f.clock.now() == 1.0 and f.clock.rejected_steps.count == 2
        f.advance(2.0)                            # the fleet goes on, in step
        wait_for(lambda: f.clock.now() == 2.0)
        assert max(f.ticks) < 3
    finally:
        f.close()


def test_a_step_number_that_goes_back_is_refused():
    f = Fleet()
    try:
        f.advance(0.5)
        wait_for(lambda: f.clock.now() == 0.5)
        forged_step(f, 0.6, step=1)               # plausible time, stale number
        assert f.clock.rejected_steps.count == 1 and f.clock.now() == 0.5
    finally:
        f.close()


def test_a_ghost_stepdone_claiming_a_billion_samples_is_dropped():
    f = Fleet()
    try:
        f.advance(0.5)
        f.forger.publish(f"{DONE}/ghost", StepDone("ghost", 0.5, {"robot1/cmd_vel": 10**9},
                                                   1.0, f.run))
        assert "ghost" not in f.barrier.done and f.barrier.dropped.count == 1
        assert f.barrier.sent().get("robot1/cmd_vel", 0) < 1000
        t0 = time.monotonic()
        f.advance(1.5)                            # no stall: nothing waits for the ghost
        wait_for(lambda: f.clock.now() == 1.5)
        assert time.monotonic() - t0 < 2.0
    finally:
        f.close()


def test_a_forged_claim_under_a_real_name_is_forgiven_at_once_then_withdrawn():
    f = Fleet()
    try:
        f.advance(0.5)
        wait_for(lambda: f.clock._acked and f.clock.now() == 0.5)
        real = f.barrier.done["robot1"]
        forged = StepDone("robot1", 0.5, {"robot1/cmd_vel": 10**9}, real.next, f.run)
        f.forger.publish(f"{DONE}/robot1", forged)  # a forger naming robot1, under its key
        t0 = time.monotonic()
        f.advance(1.0)
        assert time.monotonic() - t0 < 2.0        # not waited for: beyond MAX_IN_FLIGHT
        assert f.barrier.books.offsets.get("robot1/cmd_vel", 0) == 0  # withdrawn: later claims
        f.advance(1.5)                            # are lower, so the big one was forged
        wait_for(lambda: f.clock.now() == 1.5)
    finally:
        f.close()


def test_stepdone_checks_are_exact():
    f = Fleet()
    try:
        f.advance(0.3)
        before = f.barrier.dropped.count
        f.forger.publish(f"{DONE}/robot1", StepDone("robot2", 0.3, {}, 0.4, f.run))  # wrong key
        f.forger.publish(f"{DONE}/robot1", StepDone("robot1", 0.3, {}, 0.4, "other-x1"))
        f.forger.publish(f"{DONE}/robot1", StepDone("robot1", 99.0, {}, 100.0, f.run))  # future
        # a negative count: the claims are packed unsigned, so it would stop the simulator
        f.forger.publish(f"{DONE}/robot1", StepDone("robot1", 0.3, {"robot1/cmd_vel": -1}, 0.4,
                                                    f.run))
        assert f.barrier.dropped.count == before + 4
        f.forger.publish(f"{DONE}/robot1", StepDone("robot1", 0.3, {}, 1e9, f.run))
        assert f.barrier.done["robot1"].next == 0.3 + NEXT_HORIZON  # clamped, not for ever
    finally:
        f.close()


def test_a_participant_restarts_its_counts_and_time_with_a_new_run():
    f = Fleet(speed=2)
    try:
        f.advance(3.0)
        wait_for(lambda: f.clock.now() == 3.0 and f.clock._acked)
        assert f.clock.counts.sent["robot1/cmd_vel"] >= 30
        f.barrier.close()                         # the simulator dies; another one starts
        f.source.close()
        run2 = run_id(2)
        b2 = Barrier(f.sim_bus, run2, 2.5, wall=f.wall)
        f.barrier, f.run, f.sim_time = b2, run2, 0.0
        b2.publish(0.0)
        b2.wait(0.0, f.stop)
        assert "robot1" not in b2.unresponsive
        wait_for(lambda: f.clock.restarts == 1 and f.clock.now() == 0.0)
        wait_for(lambda: "robot1" in b2.done)
        done = b2.done["robot1"]
        assert done.run == run2 and done.next < 1.0      # due soon, not at its old time
        assert done.sent.get("robot1/cmd_vel", 0) < 5    # counts restarted with the run
        t0 = time.monotonic()
        f.advance(2.0)                             # full speed: no step waits a timeout
        assert time.monotonic() - t0 < 2.0 and not b2.unresponsive
    finally:
        f.close()


def test_a_resumed_participant_rejoins_the_current_step():
    f = Fleet(speed=2)
    try:
        f.advance(1.0)
        wait_for(lambda: f.clock._acked and f.clock.now() == 1.0)
        # the participant was stopped: the simulator gave it up and went on to t=9 meanwhile
        f.barrier.unresponsive.add("robot1")
        forged_step(f, 9.0, step=f.barrier.step + 50)  # without wall time to show for it:
        assert f.clock.now() == 1.0                     # refused (8 s beyond its next)
        f.wall.t += 6.0                                 # 6 s stopped: 6 × 3 = 18 s allowed
        f.barrier.step += 100
        f.sim_time = 9.0
        f.barrier.publish(9.0)
        f.barrier.wait(9.0, f.stop)
        wait_for(lambda: f.clock.now() == 9.0 and f.clock._acked)  # rejoined the current step
        f.advance(10.0)
        wait_for(lambda: f.clock.now() == 10.0)
        assert "robot1" not in f.barrier.unresponsive   # it answered: back in step
    finally:
        f.close()


def test_counts_that_never_arrive_are_forgiven_once_after_count_wait():
    f = Fleet()
    try:
        f.advance(0.5)
        wait_for(lambda: f.clock._acked and f.clock.now() == 0.5)
        f.agent_bus.subscribe("robot2/report", lambda s: None, msg_type=Twist)
        # a step requiring 40 samples of robot2 that were lost on a link that went down
        f.forger.publish(STEP, claiming_step(0.6, f.barrier.step + 1, {"robot2/report": 40},
                                             f.run, 2.5, table=f.barrier.table))
        time.sleep(0.1)
        assert f.clock.now() == 0.5               # waited for...
        f.wall.t += count_wait(2.5) + 0.01
        wait_for(lambda: f.clock.now() == 0.6)    # ...then forgiven
        assert f.clock._books.lost == 40 and f.clock._books.offsets["robot2/report"] == 40
    finally:
        f.close()


def test_the_clock_ignores_a_run_without_a_token_and_reports_a_second_claimant():
    wall = Wall()
    c = SimClock(wall=wall)
    real, rival = run_id(2), run_id(2)
    c.on_source(real, True)
    assert not c.on_clock(5.0, "forger")          # no token while a run holds one
    assert c.on_clock(0.02, real) and c.source == real
    c.on_source(rival, True)
    wall.t += 0.1
    assert not c.on_clock(300.0, rival) and rival in c.rivals
    assert c.on_clock(0.04, real) and c.now() == 0.04


def test_clock_creep_is_bounded_by_wall_time():
    wall = Wall()
    c = SimClock(wall=wall)
    run = run_id(2)
    c.on_source(run, True)
    for k in range(50):                           # the real run, at speed 2
        wall.t += 0.01
        assert c.on_clock(k * 0.02, run)
    start, t0 = c.now(), wall.t
    for k in range(300):                          # the probe: 9.9 s ahead each, 300 in 1.5 s
        wall.t += 0.005
        c.on_clock(c.now() + 9.9, run)
    allowed = c.max_jump + 2 * RATE_MARGIN * (wall.t - t0)
    assert c.now() - start <= allowed + 1e-6 and c.now() - start < 15
    assert c.rejected > 250


def test_a_stopped_follower_catches_up_at_once():
    wall = Wall()
    c = SimClock(wall=wall)
    run = run_id(2)
    c.on_clock(1.0, run)
    c.on_clock(1.02, run)
    wall.t += 30.0                                # stopped for 30 s: the run went on 60 s
    assert c.on_clock(61.0, run) and c.now() == 61.0


def test_speed_zero_is_bounded_by_the_ceiling():
    wall = Wall()
    c = SimClock(wall=wall)
    run = run_id(0)
    c.on_clock(0.0, run)
    c.on_clock(0.02, run)
    for _ in range(1000):
        wall.t += 0.001
        c.on_clock(c.now() + 9.0, run)
    assert c.now() <= 0.02 + c.max_jump + CEILING * 1.0 + 1e-6


@pytest.mark.slow
@settings(max_examples=200, derandomize=True, deadline=None)
@given(st.lists(st.tuples(st.floats(0, 0.5), st.floats(-50, 1e6)), max_size=60),
       st.sampled_from([0.5, 1.0, 2.0, 10.0, 0.0]))
def test_no_sequence_of_samples_with_the_real_run_id_outruns_wall_time(samples, speed):
    """Property: whatever samples a forger sends with the real run id, at whatever wall times,
    time never gets further ahead than the burst plus the run's rate × wall time elapsed."""
    wall = Wall()
    c = SimClock(wall=wall)
    run = run_id(speed)
    c.on_source(run, True)
    c.on_clock(0.0, run)
    t0 = wall.t
    for dt, stamp in samples:
        wall.t += dt
        c.on_clock(stamp, run)
        assert c.now() <= c.max_jump + run_rate(run) * (wall.t - t0) + 1e-6


def test_a_newcomer_passes_over_steps_until_it_has_the_whole_key_table():
    """Steps carry only the keys new since the previous one: a participant that
    joins mid-run passes them over until the simulator, seeing its token, sends the whole
    table — then counts by the same table as the simulator and runs in step."""
    f = Fleet()
    try:
        f.advance(0.5)
        for k in range(3):                        # keys the run claimed before robot2 came
            f.sim_bus.publish(f"robot{k + 3}/odom", Twist(0.0, 0.0))
        f.advance(1.0)
        assert len(f.barrier.table) == 4
        robot2 = f.newcomer("robot2")
        wait_for(lambda: "robot2" in f.barrier.participants)
        f.advance(2.0)
        wait_for(lambda: robot2.now() == 2.0 and f.clock.now() == 2.0)
        assert robot2._table.keys == f.barrier.table.keys[:len(robot2._table)]
        assert "robot2/cmd_vel" in f.barrier.table.index and not f.barrier.unresponsive
    finally:
        f.close()


def with_a_wrong_table(f):
    """The participant's copy of the key table replaced by another, then the simulator's loop
    to t=1.0 on a thread (returned)."""
    from mrta_zenoh.lockstep.table import KeyTable

    wrong = KeyTable()
    wrong.add({"robot9/forged"})
    with f.clock._cond:
        f.clock._table = wrong
    on = threading.Thread(target=f.advance, args=(1.0,), daemon=True)
    on.start()
    return on


def test_a_participant_whose_key_table_is_wrong_asks_for_the_whole_one():
    """A copy of the table that is not the simulator's (a step carrying keys missed, or a
    forged one taken) fails the table's digest: the participant asks the barrier's holder for
    the current step with the whole table (lockstep/sequence.py) and is in step again — no
    wall time has to pass."""
    f = Fleet(timeout=10.0)
    try:
        f.advance(0.5)
        wait_for(lambda: f.clock.now() == 0.5 and f.clock._acked)
        on = with_a_wrong_table(f)
        wait_for(lambda: f.clock.now() == 1.0, timeout=10.0)
        on.join(10)
        assert f.clock.table_waits > 0 and f.clock._sequence.asks == 1
        assert f.clock._table.keys == f.barrier.table.keys[:len(f.clock._table)]
        assert f.barrier.given_up == 0 and not f.barrier.unresponsive
    finally:
        f.close()


def test_a_participant_whose_request_is_not_honoured_gets_the_whole_table_when_silent():
    """A forger asked in its name just before (one request per REPORT_AFTER is honoured): the
    simulator still sends the whole table to a participant silent for REPORT_AFTER."""
    from mrta_zenoh.lockstep.protocol import REPORT_AFTER

    f = Fleet(timeout=10.0)
    try:
        f.advance(0.5)
        wait_for(lambda: f.clock.now() == 0.5 and f.clock._acked)
        f.forger.publish(f"{DONE}/robot1", StepDone("robot1", 0.5, {}, -1.0, f.run,
                                                    resync=True))
        f.advance(0.52)                               # honoured: a stop, the table whole
        on = with_a_wrong_table(f)
        wait_for(lambda: f.clock.table_waits > 0 and f.barrier._stamp is not None)
        assert f.clock.now() == 0.52 and f.barrier.dropped.count == 1  # its request: refused
        f.wall.t += REPORT_AFTER + 0.01
        wait_for(lambda: f.clock.now() == 1.0, timeout=10.0)
        on.join(10)
        assert f.barrier.given_up == 0 and not f.barrier.unresponsive
    finally:
        f.close()


def test_a_participant_claiming_thousands_of_keys_loses_its_claims_not_the_steps():
    """A participant (a forger holding a token, or a robot with its own certificate) that
    claims 4,096 keys of its own: its answer counts, its claims are dropped (CLAIM_KEYS), so
    the Steps stay what the others can read; once per run it counts as forgiven."""
    from mrta_zenoh.lockstep.protocol import CLAIM_KEYS, PARTICIPANT

    f = Fleet()
    try:
        f.advance(0.5)
        wait_for(lambda: f.clock.now() == 0.5 and f.clock._acked)
        claims = {f"ghost/k{i}": 1 for i in range(4 * CLAIM_KEYS)}
        # the claimant answers every step, at once, with its claims
        f.forger.subscribe(STEP, lambda s: f.forger.publish(f"{DONE}/ghost", StepDone(
            "ghost", s.message.stamp, claims, s.message.stamp + 0.1, f.run)), msg_type=Step)
        token = f.forger.declare_token(f"{PARTICIPANT}/ghost")
        wait_for(lambda: "ghost" in f.barrier.participants)
        f.forger.publish(f"{DONE}/ghost", StepDone("ghost", 0.5, claims, 0.6, f.run))
        assert f.barrier.done["ghost"].sent == {} and f.barrier.forgiven == 1
        f.advance(2.0)
        wait_for(lambda: f.clock.now() == 2.0)
        assert f.barrier.dropped.count > 2 and f.barrier.forgiven == 1  # once per run
        token.close()
        assert len(f.barrier.table) < 10 and f.clock.rejected_steps.count == 0
    finally:
        f.close()


def test_a_strangers_participant_token_is_refused_counted_and_never_waited_for():
    """A barrier told its run's members (`mrta sim --lockstep-members`, which a mission passes)
    takes no stranger into its lockstep: its token, under a name that is no process of the
    run, is counted and its StepDones dropped, and the run goes on without ever waiting for it
    (issue 51.3: a stranger was waited for, given up after the timeout, and the run called
    inexact)."""
    f = Fleet(members=frozenset({"robot1"}))
    try:
        token = f.forger.declare_token(f"{PARTICIPANT}/intruder")
        wait_for(lambda: "intruder" in f.barrier.strangers)
        f.forger.publish(f"{DONE}/intruder", StepDone("intruder", 0.0, {}, 0.5, f.run))
        assert f.barrier.participants == {"robot1"} and f.barrier.dropped.count == 2
        f.advance(2.0)
        wait_for(lambda: f.clock.now() == 2.0)
        assert f.barrier.given_up == 0 and not f.barrier.unresponsive
        token.close()
    finally:
        f.close()
