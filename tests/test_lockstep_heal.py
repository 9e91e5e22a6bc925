"""Lockstep heals from any single forged sample: each forgery a hostile probe sent on
an open bus, on the in-process bus with a hand-moved wall clock, so a bound in wall seconds is
checked by how far the wall clock had to be moved — not by how long the machine took.
tests/process/test_lockstep_attacks.py replays them with processes."""

import threading

import msgspec

from mrta_zenoh.lockstep.books import Books, claimant
from mrta_zenoh.lockstep.protocol import (DONE, FORGIVE_WINDOW, PARTICIPANT, REPORT_AFTER, STEP,
                                          Step, StepDone, count_wait)
from mrta_zenoh.lockstep.table import Claims, KeyTable
from mrta_zenoh.messages import Twist
from tests.harness.helpers import wait_for
from tests.test_lockstep_trust import Fleet


def copied(f, **changes):
    """The step the simulator published last, as a forger copies it, with `changes`."""
    return msgspec.structs.replace(f.barrier._last, **changes)


def advancing(f, until):
    """The simulator's loop to `until` on a thread (a stuck fleet must fail the test, not hang
    it: close() stops the barrier's wait)."""
    thread = threading.Thread(target=f.advance, args=(until,), daemon=True)
    thread.start()
    return thread


def test_a_copied_step_numbered_a_billion_is_not_believed():
    """The probe: one real Step copied with step 10⁹ — every agent then refused every real
    step ("step 63 after step 1000000000") for the rest of the run."""
    f = Fleet()
    try:
        f.advance(1.0)
        wait_for(lambda: f.clock.now() == 1.0 and f.clock._acked)
        f.forger.publish(STEP, copied(f, step=10**9))
        assert f.clock._sequence.number < 10**9 and f.clock.rejected_steps.count == 1
        on = advancing(f, 3.0)
        wait_for(lambda: f.clock.now() == 3.0)    # in step: no wall time had to pass
        on.join(10)
        assert not on.is_alive() and f.barrier.given_up == 0
    finally:
        f.close()


def test_an_old_whole_step_replayed_as_the_next_one_is_resynchronised_at_once():
    """The probe: an old whole-table Step, its digest genuine, numbered current + 1 — it
    would shadow the real next step (dropped as a duplicate) and leave the participant with
    the old table, every agent stuck. The real step contradicts it, the participant asks, and
    the barrier's whole step puts it right."""
    f = Fleet()
    try:
        f.advance(0.1)
        old = f.barrier._whole_step(f.barrier._last)   # step 1's, whole, genuine digest
        for k in range(3):                            # keys the run claims later
            f.sim_bus.publish(f"robot{k + 3}/odom", Twist(0.0, 0.0))
        f.advance(1.0)
        wait_for(lambda: f.clock.now() == 1.0 and f.clock._acked)
        f.forger.publish(STEP, msgspec.structs.replace(old, step=f.barrier.step + 1))
        on = advancing(f, 3.0)
        wait_for(lambda: f.clock.now() == 3.0)
        on.join(10)
        assert f.clock._sequence.asks >= 1            # it asked, and was answered
        assert f.clock._table.keys == f.barrier.table.keys[:len(f.clock._table)]
        assert f.barrier.given_up == 0 and not f.barrier.unresponsive
    finally:
        f.close()


def test_a_forged_next_step_that_moves_time_ahead_costs_no_pause():
    """A copy numbered as the next step, stamped as far ahead as the participant's budget
    allows: taken (nothing tells it from the real one yet). The real steps are then behind
    its time: it answers them at once, keeps its time, and is in step when the run gets
    there."""
    f = Fleet()
    try:
        f.advance(1.0)
        wait_for(lambda: f.clock.now() == 1.0 and f.clock._acked)
        f.forger.publish(STEP, copied(f, step=f.barrier.step + 1, stamp=1.6))
        wait_for(lambda: f.clock.now() == 1.6)
        on = advancing(f, 3.0)
        wait_for(lambda: f.clock.now() == 3.0)
        on.join(10)
        assert not on.is_alive() and f.barrier.given_up == 0
        assert f.clock.now() == 3.0 and max(f.ticks) < 3.05
    finally:
        f.close()


def test_while_every_participant_is_given_up_the_whole_table_still_goes_out():
    """Once every participant was given up, due() never stopped again, and the whole-table
    resend promised every REPORT_AFTER never came."""
    from mrta_zenoh.bus.inproc import InProcBus, InProcNetwork
    from mrta_zenoh.lockstep.barrier import Barrier
    from tests.harness.helpers import Wall

    net, wall, stop = InProcNetwork(), Wall(), threading.Event()
    barrier = Barrier(InProcBus(net), "run1-x1", 2.5, wall=wall)
    hung = InProcBus(net)
    token = hung.declare_token(f"{PARTICIPANT}/robot1")   # alive, and never answers
    steps = []
    hung.subscribe(STEP, lambda s: steps.append(s.message), msg_type=Step)
    try:
        barrier.publish(0.0)
        waiting = threading.Thread(target=barrier.wait, args=(0.0, stop), daemon=True)
        waiting.start()
        wait_for(lambda: barrier._stamp is not None)
        wall.t += 2.5                                      # the timeout: given up
        waiting.join(10)
        assert barrier.unresponsive == {"robot1"}
        stamps = [round(0.02 * k, 6) for k in range(1, 200)]
        stops = [t for t in stamps[:100] if barrier.due(t) and barrier.publish(t) is None]
        assert len(stops) == 1 and steps[-1].base == 0        # one stop, the table whole
        wall.t += REPORT_AFTER
        assert [t for t in stamps[100:] if barrier.due(t) and barrier.publish(t) is None] == \
            [stamps[100]] and steps[-1].base == 0              # and again REPORT_AFTER later
    finally:
        stop.set()
        token.close()
        barrier.close()


class Relay:
    """A forger that follows every real StepDone of robot1 with a copy claiming `level`
    samples of robot1/cmd_vel — after the real one, so the simulator goes by the forged claim."""

    def __init__(self, f):
        self.f, self.level, self.busy = f, None, False
        f.forger.subscribe(f"{DONE}/robot1", self._on, msg_type=StepDone)

    def _on(self, sample):
        if self.busy or self.level is None:
            return
        self.busy = True
        try:
            self.f.forger.publish(f"{DONE}/robot1", msgspec.structs.replace(
                sample.message, sent={"robot1/cmd_vel": self.level}))
        finally:
            self.busy = False


def paused(f, until):
    """Advance to `until` with a forged claim unmet: the barrier waits (wall time would have to
    pass); the thread, to be let go by moving the wall clock. Paused: at two of the thread's
    readings of the wall in a row, the barrier waits on the same step with every participant
    answered — so it has noted when they answered before the wall moves (one look could catch
    the end of an earlier step, and the pause then start a step of the wall later)."""
    on, held = advancing(f, until), None
    while True:
        f.wall.read.pop(on.ident, None)
        wait_for(lambda: on.ident in f.wall.read, 30)     # a hang guard, not a speed asserted
        with f.barrier._cond:
            step = f.barrier._stamp if not f.barrier._waiting else None
        if step is not None and step == held:
            return on
        held = step


def let_go(f, on, held=0.0, step=0.25):
    """Move the wall clock until the barrier forgives the claim that pauses `on` — by `held` at
    once (`on` must still be paused after it), then in steps; how far it had to move. Driven
    by events, not by the machine's speed: a move is made only once `on` (the barrier's wait)
    has read the last one and decided on it — it reads the wall and forgives under the
    barrier's lock, so taking that lock after its reading sees its decision."""
    forgiven, moved = f.barrier.forgiven, 0.0
    while f.barrier.forgiven == forgiven:
        assert moved < 60, "still paused after a minute of wall time"
        move = held if moved == 0.0 and held > 0 else step
        f.wall.t += move
        moved += move
        wait_for(lambda: f.wall.read.get(on.ident, 0.0) >= f.wall.t or not on.is_alive(), 30)
        with f.barrier._cond:
            pass
    on.join(30)                                       # a hang guard, not a speed asserted
    assert not on.is_alive()
    assert moved > held, "forgiven before `held` wall seconds"
    return moved


def test_a_descending_claim_pauses_the_run_once_per_window():
    """The probe: a claim under a real participant's name lowered by 1 every 5.2 s withdraws
    each forgiveness, and would pause the fleet again each time — 8 pauses in 45 s. The first
    costs count_wait; within FORGIVE_WINDOW the claimant's unmet claims are forgiven at once."""
    f = Fleet(timeout=10.0)
    relay = Relay(f)
    try:
        f.advance(0.5)
        wait_for(lambda: f.clock.now() == 0.5 and f.clock._acked)
        relay.level = f.barrier.done["robot1"].sent["robot1/cmd_vel"] + 50
        on = paused(f, 0.7)
        assert on.is_alive() and f.barrier.forgiven == 0     # the one pause: count_wait
        assert let_go(f, on, held=count_wait(10.0) - 0.25) <= count_wait(10.0) + 0.25
        assert f.barrier.forgiven == 1
        for k in range(1, 8):                                # lowered by 1, again and again
            relay.level -= 1
            on = advancing(f, round(0.7 + 0.2 * k, 6))
            on.join(10)
            assert not on.is_alive()                         # no wall time had to pass
        assert f.barrier.forgiven == 1
        f.wall.t += FORGIVE_WINDOW                           # the window closes: waited again
        relay.level += 100
        on = paused(f, 2.5)
        assert on.is_alive()
        assert let_go(f, on, held=count_wait(10.0) - 0.25) <= count_wait(10.0) + 0.25
        assert f.barrier.forgiven == 2
    finally:
        f.close()


def test_a_participant_may_claim_only_under_its_own_name():
    """What a robot's role may publish on a secured fleet (robotN/**): a claim elsewhere, or on
    a key the simulator publishes itself, is dropped, not waited for."""
    f = Fleet()
    try:
        f.advance(0.5)
        wait_for(lambda: f.clock.now() == 0.5 and f.clock._acked)
        real = f.barrier.done["robot1"]
        f.forger.publish(f"{DONE}/robot1", msgspec.structs.replace(
            real, sent={**real.sent, "robot2/cmd_vel": 10**6}))
        assert f.barrier.done["robot1"].sent == {} and f.barrier.dropped.count == 1
        f.forger.publish(f"{DONE}/robot1", msgspec.structs.replace(
            real, sent={**real.sent, "robot1/x" * 40: 1}))          # a key of 320 characters
        assert f.barrier.dropped.count == 2
        f.forger.publish(f"{DONE}/robot1", msgspec.structs.replace(real, sent={}))
        f.barrier.counts.sent["robot1/odom"] = 4                   # the simulator's own key
        f.forger.publish(f"{DONE}/robot1", msgspec.structs.replace(
            real, sent={"robot1/odom": 10**6}))
        assert f.barrier.sent()["robot1/odom"] == 4
    finally:
        f.close()


def test_books_forgive_a_claimant_at_once_within_its_window():
    """The participant's side of the window: its books, for the claims a step carries."""
    from mrta_zenoh.bus.inproc import InProcBus
    from tests.harness.helpers import Wall

    wall = Wall()
    with InProcBus() as bus:
        counts = bus.enable_counting()
        books, table = Books(counts, wall), KeyTable()
        bus.subscribe("*/alliance/**", lambda s: None)
        table.add({"robot2/alliance/irc", "robot3/alliance/irc"})
        step = Claims(table, [5, 5])
        missing = books.missing(step)
        assert missing == {"robot2/alliance/irc": 5, "robot3/alliance/irc": 5}
        assert books.at_once(missing) == {}                   # waited for: count_wait
        assert books.forgive({"robot2/alliance/irc": 5}, step)  # news: counted, logged
        later = Claims(table, [9, 9])
        assert books.at_once(books.missing(later)) == {"robot2/alliance/irc": 4}
        assert not books.forgive({"robot2/alliance/irc": 4}, later)  # no news: no count
        wall.t += FORGIVE_WINDOW
        assert books.at_once(books.missing(Claims(table, [12, 12]))) == {}
    assert claimant("robot2/alliance/irc") == "robot2"


def test_a_participant_token_without_claims_is_still_waited_for():
    """The caps drop claims, not answers: a claimant over its cap is stopped for as usual."""
    f = Fleet()
    try:
        f.advance(0.5)
        token = f.forger.declare_token(f"{PARTICIPANT}/ghost")
        wait_for(lambda: "ghost" in f.barrier.participants)
        f.forger.publish(f"{DONE}/ghost", StepDone("ghost", 0.5, {"robot1/cmd_vel": 1}, 0.56,
                                                   f.run))
        assert f.barrier.done["ghost"].next == 0.56 and f.barrier.done["ghost"].sent == {}
        assert f.barrier.due(0.56)
        token.close()
    finally:
        f.close()
