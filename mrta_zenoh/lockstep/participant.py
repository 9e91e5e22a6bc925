"""A participant's side of lockstep: its clock (`LockstepClock`), whose time moves with the
simulator's steps once everything they claim has arrived."""

from __future__ import annotations

import contextlib
import threading
import time
from typing import Callable

from ..clock import CEILING, EPSILON, SimClock, run_rate
from ..untrusted import visible
from .books import Books
from .protocol import (BARRIER, DONE, MAX_KEYS, MAX_NAMES, PARTICIPANT, SPEAKS, STEP,
                       STEP_BURST, STEP_SLACK, WORK_BEAT, WORK_CPU, Rejections, Step, StepDone,
                       count_wait, log)
from .sequence import Sequence
from .table import Claims, KeyTable, count_of

BEHIND = "behind"  # _judge: a step this participant's time is already past


class StepBudget:
    """How far beyond its own `next` a participant's time may be moved: `rate` simulated seconds
    per wall second (the run's speed), a burst of STEP_BURST — or, after a wall gap (this process
    was stopped while the simulator went on), what the gap allows."""

    def __init__(self, rate: float, wall: Callable[[], float]) -> None:
        self.rate = rate
        self._wall = wall
        self._at = wall()
        self._budget = STEP_BURST

    def refill(self) -> float:
        now = self._wall()
        earned = self.rate * max(0.0, now - self._at)
        self._at = now
        self._budget = min(self._budget + earned, max(STEP_BURST, earned))
        return self._budget

    def affords(self, amount: float) -> bool:
        return amount <= self._budget + EPSILON

    def spend(self, amount: float) -> bool:
        if not self.affords(amount):
            return False
        self._budget = max(0.0, self._budget - amount)
        return True


class LoopCpu:
    """The CPU time (s) of a participant's loop thread — the one that last called `sleep_until`
    (at first, the one that joined) — or None if unknown: what tells a participant computing a
    long decision from one whose loop is stuck (blocked, deadlocked), which uses none.

    Read from /proc/self/task/<tid>/schedstat (ns; Linux), not through pthread_getcpuclockid:
    a thread that has ended may have its pthread_t reused, and asking its clock is then
    undefined, where the task id of a thread gone just reads as nothing. Without /proc (not
    Linux) this reads None: a participant then never says it is working, and a long
    computation is given up after the barrier's timeout, as a hung loop is."""

    def __init__(self) -> None:
        self.thread = threading.current_thread()

    def follow(self, thread: threading.Thread) -> None:
        self.thread = thread

    def __call__(self) -> float | None:
        thread = self.thread
        if not thread.is_alive() or thread.native_id is None:
            return None
        try:
            with open(f"/proc/self/task/{thread.native_id}/schedstat", "rb") as f:
                return int(f.read().split()[0]) / 1e9
        except (OSError, ValueError, IndexError):
            return None


class LockstepClock(SimClock):
    """A participant's clock: simulation time that also moves in lockstep when the simulator
    runs it (and follows the plain `clock` key otherwise)."""

    def __init__(self, participant: str, wall=time.monotonic,
                 speaks_for: tuple[str, ...] = (), cpu: LoopCpu | None = None) -> None:
        """`cpu`: the loop thread's CPU time (LoopCpu; a test injects its own)."""
        super().__init__(wall=wall)
        self.participant = participant
        # the robots this participant answers for besides itself (an agent host's): one SPEAKS
        # token each, declared before its participant token, so the barrier takes its claims
        # under their names from its first answer
        self.speaks_for = tuple(r for r in speaks_for if r != participant)
        self.lockstep = threading.Event()
        self.run: str | None = None           # the lockstep run whose steps move time
        self.rejected_steps = Rejections(f"step for {visible(participant, 80)}")
        self.step_rivals: set[str] = set()
        self.counts = None                    # the bus's lockstep counts, once joined
        self._books: Books | None = None
        self._table = KeyTable()              # the run's keys, as its steps name them
        self.table_waits = 0                  # steps passed over while waiting for a whole table
        self._barriers: set[str] = set()      # runs whose barrier token lives
        self._sequence = Sequence(wall)       # the steps believed (lockstep/sequence.py)
        self._ask = False                     # _judge: ask the barrier for a whole step
        self._step_budget = StepBudget(CEILING, wall)
        self._pending: Step | None = None
        self._claims: Claims | None = None    # the pending step's
        self._pending_wall = 0.0
        # the pending step's keys found missing at the last look (None: look at all of them):
        # each sample received while a step is pending looks again, at these only
        self._still_missing: list[str] | None = None
        self._new_run = False                 # the pending step opens a new run
        self._refused: Step | None = None     # a new run's step refused while the old one lives
        self._timer: threading.Timer | None = None  # looks at a pending step's counts again
        self._acked = True
        self._sleeping_until: float | None = None  # the main loop waits for this time
        self._publish_done: Callable[..., None] | None = None
        self._publish_working: Callable[[float], None] | None = None
        self.forgiven = 0  # claims forgiven in this run (a new run starts again)
        self._cpu = LoopCpu() if cpu is None else cpu
        self._cpu_seen: float | None = None   # the loop thread's CPU time at the last beat()

    def in_lockstep(self) -> bool:
        return self.lockstep.is_set()

    def join(self, bus) -> contextlib.ExitStack:
        """Count traffic, follow steps, and announce the participant; returns the handles as
        one ExitStack (closing it leaves the barrier)."""
        # while steps are pending, every received sample may be the one they wait for
        counts = self.counts = bus.enable_counting(self._release)
        self._books = Books(counts, self._wall)
        done_key = f"{DONE}/{self.participant}"

        def publish_done(stamp: float, next_due: float, resync: bool = False) -> None:
            bus.publish(done_key, StepDone(self.participant, stamp, counts.claims(),
                                           next_due, self.run or "", self.forgiven, resync))

        def publish_working(stamp: float) -> None:
            bus.publish(done_key, StepDone(self.participant, stamp, {}, -1.0, self.run or "",
                                           self.forgiven, working=True))

        self._publish_done, self._publish_working = publish_done, publish_working
        handles = [bus.watch_liveliness(f"{BARRIER}/*", self._on_barrier),
                   bus.subscribe(STEP, self._on_step, msg_type=Step)]
        handles.extend(bus.declare_token(f"{SPEAKS}/{self.participant}/{robot}")
                       for robot in self.speaks_for)
        handles.append(bus.declare_token(f"{PARTICIPANT}/{self.participant}"))
        stack = contextlib.ExitStack()
        stack.callback(counts.close)
        for h in handles:
            stack.callback(h.close)
        self._cpu_seen = self._cpu()
        stop = threading.Event()  # the beats stop first when the stack closes (last in)
        beats = threading.Thread(target=self._beating, args=(stop,), daemon=True,
                                 name=f"lockstep-beat-{self.participant}")
        beats.start()
        stack.callback(beats.join, 2 * WORK_BEAT)
        stack.callback(stop.set)
        return stack

    def _beating(self, stop: threading.Event) -> None:
        while not stop.wait(WORK_BEAT):
            self.beat()

    def beat(self) -> bool:
        """One look (every WORK_BEAT wall s): if this participant owes the barrier an answer
        and its loop thread is working — not waiting in `sleep_until`, and its CPU time grew by
        WORK_CPU since the last look — say so (StepDone `working`), so that the barrier waits
        for it past its timeout: a decision that takes longer than the timeout on a busy
        machine must not change the run. A loop that is stuck uses no CPU time and says
        nothing; a stopped or dead process says nothing either. True if it said so."""
        cpu = self._cpu()
        with self._cond:
            last, self._cpu_seen = self._cpu_seen, cpu
            owes = self.lockstep.is_set() and not self._acked and self._sleeping_until is None
            stamp = self._now
        if not owes or cpu is None or last is None or cpu - last < WORK_CPU or \
                self._publish_working is None:
            return False
        self._publish_working(stamp)
        return True

    def _on_barrier(self, key: str, alive: bool) -> None:
        run = key.rsplit("/", 1)[-1]
        retry = None
        with self._cond:
            if alive:
                if len(self._barriers) < MAX_NAMES:
                    self._barriers.add(run)
            else:
                self._barriers.discard(run)
                if run == self.run:  # its simulator is gone: the clock decides again
                    self.lockstep.clear()
                    self._source_alive = False
                    retry, self._refused = self._refused, None
                    # counts restart with the next run: a new simulator counts from zero, so
                    # the counts of this one would be claims it can never meet. Not when the
                    # new run's first step comes: its sensor data, counted just before, would
                    # be lost from the books.
                    self._books.reset()
                    self._table = KeyTable()
                    self.forgiven = 0
                    self._still_missing = None
        if retry is not None:
            self._offer(retry)

    def on_clock(self, stamp: float, source: str = "") -> bool:
        if self.lockstep.is_set():
            return False  # steps, not the lossy clock, move time in lockstep
        return super().on_clock(stamp, source)

    def _on_step(self, sample) -> None:
        self._offer(sample.message)

    def _offer(self, step: Step) -> None:
        done = None
        with self._cond:
            why = self._judge(step)
            ask = self._ask
            self._ask = False
            if why == BEHIND:
                # this participant's time is past the run's (a forged step moved it): it did
                # that time already, so it is done with this step at once and keeps its time
                self._pending, self._still_missing = None, None
                due = self._sleeping_until if self._sleeping_until is not None else self._now
                done = (step.stamp, due)
                self._acked = True  # what it does now, it says at the step there
            elif why == "":
                pass  # the step again (re-published for a newcomer), or one it cannot read yet
            elif why is not None:
                self.rejected_steps(why)
            else:
                self.lockstep.set()
                self._pending = step
                self._claims = Claims.of(self._table, step)
                self._pending_wall = self._wall()
                self._still_missing = None
        if ask:  # the barrier's holder sends its current step with the whole table
            self._publish_done(self._now, -1.0, True)
        if done is not None:
            self._publish_done(*done)
        elif why is None:
            self._release()

    def _judge(self, step: Step) -> str | None:
        """None: take it; "": a duplicate, or passed over; BEHIND: taken, but this participant's
        time is past it; otherwise why it is refused. Sets `_ask` when the step contradicts
        what was taken (lockstep/sequence.py). Under self._cond."""
        if count_of(step) > MAX_KEYS:
            return f"it counts {count_of(step)} keys (at most {MAX_KEYS})"
        if step.run != self.run:
            if step.run not in self._barriers:
                return f"run {visible(step.run, 80)!r} holds no barrier token"
            if self.run is not None and self.run in self._barriers:
                if step.run not in self.step_rivals and len(self.step_rivals) < MAX_NAMES:
                    self.step_rivals.add(step.run)
                    log.warning("lockstep: a second lockstep run %r while %r runs: ignored",
                                visible(step.run, 80), visible(self.run, 80))
                self._refused = step
                return f"run {visible(step.run, 80)!r} while {visible(self.run, 80)!r} runs"
            table = KeyTable()
            why = self._take_table(table, step)
            if why is not None:
                return why
            if self.run is not None:
                # what it sent between two runs (its clock watchdog's stop) the new run's
                # simulator may never have heard: claimed, it would be waited for at every step
                # and met only by the watchdog's next stop, 2 s later — one step per 2 s
                self.counts.sent.clear()
            self.run, self._new_run = step.run, True
            self._sequence.restart(step)
            self._table = table
            self._step_budget = StepBudget(run_rate(step.run) or CEILING, self._wall)
            return None
        sequence = self._sequence
        if sequence.again(step):
            return ""
        if not sequence.answers(step):
            why = sequence.follows(step)
            if why is not None:
                self._ask = sequence.contradicted()
                return why
        self._step_budget.refill()
        due = self._sleeping_until if self._sleeping_until is not None else self._now
        beyond = step.stamp - (max(due, self._now) + STEP_SLACK)
        if beyond > EPSILON and not self._step_budget.affords(beyond):
            return (f"t={step.stamp:.3f} is beyond this participant's next (t={due:.3f}) by "
                    f"more than wall time allows")
        why = self._take_table(self._table, step)  # a step passed over spends no budget
        if why == "":  # this copy of the table cannot read it: ask for the whole one
            self._ask = sequence.contradicted()
        if why is not None:
            return why
        if beyond > EPSILON:
            self._step_budget.spend(beyond)
        sequence.accept(step)
        return BEHIND if step.stamp < self._now - EPSILON else None

    def _take_table(self, table: KeyTable, step: Step) -> str | None:
        """The step's keys into `table` (KeyTable.take); a step that cannot be known yet is
        passed over quietly (counted): a whole table comes to a newcomer, to a participant that
        asks, to one silent for REPORT_AFTER and to one given up."""
        why = table.take(step)
        if why == "":
            self.table_waits += 1
            log.debug("lockstep: step %d passed over: waiting for the whole key table", step.step)
        return why

    def _release(self) -> None:
        """Move time to the pending step once everything it requires has arrived (or is
        forgiven). If the main loop is already waiting for a later time, it has nothing to do
        now: done at once. A new run restarts time: the main loop wakes and reschedules.

        Called for every sample counted: with no step pending (most samples, once a step is
        released) it returns without taking the lock — a step that becomes pending after this
        look is looked at by `_offer` itself, after this sample was counted."""
        if self._pending is None:
            return
        with self._cond:
            step = self._pending
            if step is None:
                return
            books = self._books
            claims = self._claims
            withdrawn = books.review(claims)
            missing = books.missing(claims, None if withdrawn else self._still_missing)
            self._still_missing = list(missing)
            if missing:
                left = count_wait(step.timeout) - (self._wall() - self._pending_wall)
                gaps = missing if left <= 0 else books.at_once(missing)
                if gaps and books.forgive(gaps, claims):
                    self.forgiven += 1  # told to the simulator in every StepDone (LockstepStatus)
                    log.warning("lockstep: %s: %d samples on %s never arrived by t=%.2f: "
                                "forgiven", visible(self.participant, 80), sum(gaps.values()),
                                ", ".join(visible(k, 80) for k in sorted(gaps)[:3]), step.stamp)
                if len(gaps) < len(missing):
                    self._still_missing = [k for k in missing if k not in gaps]
                    if self._timer is None:  # look again then, even if nothing arrives
                        self._timer = threading.Timer(left + 0.01, self._recheck)
                        self._timer.daemon = True
                        self._timer.start()
                    return
            books.settle(claims)
            self._pending = None
            self._still_missing = None
            restarted = False
            if self._new_run:
                self._new_run = False
                if self.source is not None and self.source != step.run:
                    restarted = True
                    self.restarts += 1
                    log.warning("lockstep: new simulation run %r adopted at t=%.3f (was %r at "
                                "t=%.3f)", visible(step.run, 80), step.stamp,
                                visible(self.source, 80), self._now)
                self.source, self._source_alive = step.run, True
                self._rate = run_rate(step.run)
            self._now = step.stamp
            idle = not restarted and self._sleeping_until is not None and \
                self._sleeping_until > step.stamp + EPSILON
            self._acked = idle
            self._last_wall = self._wall()
            self._cond.notify_all()
        self.started.set()
        if idle:
            self._publish_done(step.stamp, self._sleeping_until)

    def _recheck(self) -> None:
        with self._cond:
            self._timer = None
        self._release()

    def sleep_until(self, t: float, stop: threading.Event | None = None) -> bool:
        """Before waiting for a later time, tell the simulator this participant is done with
        the current one (its commands were published before, on the same link). While waiting,
        a pending step whose counts do not arrive is looked at again (to forgive them)."""
        self._cpu.follow(threading.current_thread())
        with self._cond:
            if t > self._now + EPSILON and not self._acked and self._publish_done is not None:
                self._acked = True
                stamp = self._now
            else:
                stamp = None
            self._sleeping_until = t
            epoch = self.restarts
        if stamp is not None:
            self._publish_done(stamp, t)
        try:
            while True:
                with self._cond:
                    if self._now >= t - EPSILON or self.restarts != epoch:
                        return True
                    if stop is not None and stop.is_set():
                        return False
                    self._cond.wait(0.05)
                    pending = self._pending is not None
                if pending:
                    self._release()
        finally:
            with self._cond:
                self._sleeping_until = None

