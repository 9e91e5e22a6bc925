"""The simulator's side of lockstep: the `Barrier` — whom to wait for, and waiting.

What keeps one forged sample from stopping the run here (docs/security.md): a participant's
claims within the caps of its role (ledger.py); a participant that asks for the current step
with the whole table (a StepDone with `resync`: a step contradicted what it took) gets it at
the next physics step — one request per participant per REPORT_AFTER is honoured, so forged
requests cost at most that many extra stops; and while any participant is given up the
barrier stops every REPORT_AFTER to send it the whole table, whatever else is given up (with
every participant given up, nobody is due: without this stop no step, and no table, would go
out again)."""

from __future__ import annotations

import itertools
import threading
import time
from typing import Callable

import msgspec

from ..clock import EPSILON
from ..untrusted import visible
from ..keys import CLOCK_SOURCE_TOKEN
from ..lifecycle import Closing
from ..messages import Header
from ..refusal_tally import refused_key, tally
from .books import Books
from .ledger import Ledger
from .protocol import (BARRIER, DEFAULT_TIMEOUT, DONE, ENDED_AFTER, MAX_KEYS, MAX_NAMES,
                       NEXT_HORIZON, OUTLIVED, OUTLIVED_AFTER, PARTICIPANT, REPORT_AFTER, SPEAKS,
                       STATUS, STEP, WORK_LIMIT, LockstepStatus, Rejections, Step, StepDone,
                       count_wait, log)
from .table import Claims, KeyTable, count_of


class Barrier(Closing):
    """The simulator's side: whom to wait for, and waiting. A context manager: leaving it
    withdraws the barrier's token and subscriptions (close()).

    Cost per step (100 participants answering every step): an answer updates who is still
    waited for, the per-key claims and the due cache in O(its own keys); only the last answer
    (then the counts it waits for) wakes wait() — waking on every answer and every counted
    sample, each wake rescanning every participant's StepDone, would be quadratic."""

    def __init__(self, bus, run_id: str, timeout: float = DEFAULT_TIMEOUT,
                 wall=time.monotonic, members: frozenset[str] | None = None,
                 ended: Callable[[], frozenset[str]] | None = None, name: str = "simulator"):
        """`members`: the names that may take part (a mission's processes, `mrta sim
        --lockstep-members`); None: anyone holding a participant token. A token under another
        name is a stranger's: refused and counted (`dropped`), never waited for — on a shared
        bus a stranger would otherwise be waited for, given up after the timeout, and make
        every run inexact (issue 51.3). `ended`: the members whose process has ended, as the
        run's runner says (ended.py, `mrta sim --lockstep-ended`): one the barrier waits for
        is no longer waited for once ENDED_AFTER late, whatever token lives under its name (a
        forger's keeps it alive on an open bus), and its StepDones are refused from then on.
        That is what the run does when such a process's token goes with it, so the run stays
        exact; a token that outlives its process by OUTLIVED_AFTER is a forger's (an ended
        process's token goes with its session at once, or after the 3 s lease): counted in
        what `name` (the simulator) says it refused, as forged (mrta_zenoh/refusal_tally.py),
        so that the summary names it and calls the run disturbed."""
        self.bus = bus
        self.run = run_id
        self.timeout = timeout
        self.members = members
        self.strangers: set[str] = set()  # refused participant names (at most MAX_NAMES)
        self.ended = ended
        self.name = name
        self.gone: dict[str, float] = {}  # member ended (`ended`) while waited for → wall time
        self.outlived: set[str] = set()  # of those, whose token lived on OUTLIVED_AFTER later
        self.participants: set[str] = set()
        self.ledger = Ledger()
        self.done = self.ledger.done  # participant → its last answer
        self.unresponsive: set[str] = set()
        self.rivals: set[str] = set()
        self.given_up = 0   # participants given up, this run (LockstepStatus)
        self.forgiven = 0   # claims forgiven, this run
        self._report_at = 0.0  # wall time wait() reports the participants still silent
        self._their_forgiven: dict[str, int] = {}  # participant → claims it forgave (StepDone)
        self._tell = False  # a participant forgave more: publish the status
        self.table = KeyTable()  # the run's keys, as its steps name them
        self._whole = True       # the next step carries the whole table (a newcomer appeared)
        self._resend_at = 0.0    # wall time the whole table goes again to those given up
        self._asked: dict[str, float] = {}  # participant → wall time its request was honoured
        self._resync = False     # a request honoured: stop at the next step, the table whole
        self.dropped = Rejections("StepDone")
        self._wall = wall
        self._cond = threading.Condition()
        self._changed, self._changed_at = 0, wall()
        self._ended_read = -float("inf")  # wall time `ended` was last read
        self._last: Step | None = None  # the step published last (re-published for newcomers)
        self._republish = False
        self._back: set[str] = set()  # given up, and answering again
        # Kept up to date as StepDones arrive, so a step costs one look per answer, not a scan
        # of every participant per answer (100 participants answer every step)
        self._stamp: float | None = None  # the step wait() is waiting on
        self._waiting: set[str] = set()   # participants it still waits for
        self._working: dict[str, float] = {}  # waited for → wall time of its last work beat
        self._told_working: set[str] = set()  # said to be still computing, this step
        self._due_at: float | None = None  # due() before this stamp is False (None: unknown)
        # before the commands' subscription (SimNode) exists: commands are counted from the first
        self.counts = bus.enable_counting(self._poke)
        self.books = Books(self.counts, wall)
        self.handles = [
            # before the participants': a host declares what it speaks for before it takes part
            bus.watch_liveliness(f"{SPEAKS}/*/*", self._on_voice),
            bus.watch_liveliness(f"{PARTICIPANT}/*", self._on_participant),
            bus.subscribe(f"{DONE}/*", self._on_done, msg_type=StepDone),
            bus.watch_liveliness(f"{CLOCK_SOURCE_TOKEN}/*", self._on_source),
            bus.watch_liveliness(f"{BARRIER}/*", self._on_source),
            bus.declare_token(f"{BARRIER}/{run_id}"),
        ]
        self.step = 0

    def settle(self, quiet: float = 0.5, limit: float = 3.0) -> None:
        """Give participants that are already up the time to be heard: until the set has not
        changed for `quiet` seconds (a new session first has to reach every peer)."""
        deadline = self._wall() + limit
        with self._cond:
            while self._wall() < deadline:
                changed = self._changed
                self._cond.wait(min(quiet, max(0.0, deadline - self._wall())))
                if self._changed == changed and self._wall() - self._changed_at >= quiet:
                    return

    def _on_voice(self, key: str, alive: bool) -> None:
        """A participant says it answers for a robot (an agent host), or no longer does."""
        name, robot = key[len(SPEAKS) + 1:].split("/", 1)
        with self._cond:
            if not self.ledger.speaks_for(name, robot, alive):
                self.dropped(f"{_printable(name)!r} speaks for too many robots: "
                             f"{_printable(robot)!r} ignored")
                return
            self._changed += 1
            self._changed_at = self._wall()
            self._cond.notify_all()

    def voiced(self) -> set[str]:
        """The robots some participant answers for: the participants themselves and those their
        hosts speak for (the simulator's `--wait-robots` waits for these)."""
        with self._cond:
            out = set(self.participants)
            for name in self.participants:
                out |= self.ledger.voices.get(name, set())
            return out

    def _on_participant(self, key: str, alive: bool) -> None:
        name = key.rsplit("/", 1)[-1]
        if self.members is not None and name not in self.members:
            self._stranger(name, alive)
            return
        with self._cond:
            self._changed += 1
            self._changed_at = self._wall()
            self._due_at = None
            if alive:
                if len(self.participants) < MAX_NAMES:
                    self.participants.add(name)
                    self._republish = True  # a newcomer (or a resumed one) gets the step at once
                    self._whole = True      # with the whole key table, as the next one
                    if self._stamp is not None and name not in self.unresponsive and \
                            name not in self.gone and not self._answered(name, self._stamp):
                        self._waiting.add(name)
            else:
                self.participants.discard(name)
                self._waiting.discard(name)
                self.ledger.forget(name)
                self._asked.pop(name, None)
                self.unresponsive.discard(name)
            self._cond.notify_all()

    def _stranger(self, name: str, alive: bool) -> None:
        """A participant token under a name that is none of the run's members: counted once
        per name (within MAX_NAMES), logged, never waited for; its StepDones are then dropped
        as a non-participant's."""
        with self._cond:
            if not alive or name in self.strangers or len(self.strangers) >= MAX_NAMES:
                return
            self.strangers.add(name)
            self.dropped(f"{visible(name, 80)!r} holds a participant token but is no member of "
                         "this run: not waited for")

    def _on_source(self, key: str, alive: bool) -> None:
        """Another clock source or lockstep run on this bus: one source per run, so an alarm."""
        run = key.rsplit("/", 1)[-1]
        if not alive or run == self.run:
            return
        with self._cond:
            if run in self.rivals or len(self.rivals) >= MAX_NAMES:
                return
            self.rivals.add(run)
            stamp = self._last.stamp if self._last is not None else 0.0
        log.warning("lockstep: another clock source %r is on the bus beside this run %r: two "
                    "simulators (or a forger); participants follow only this one",
                    visible(run, 80), visible(self.run, 80))
        self._status(stamp)

    def _on_done(self, sample) -> None:
        d: StepDone = sample.message
        name = sample.key.rsplit("/", 1)[-1]
        with self._cond:
            published = self._last.stamp if self._last is not None else None
            if d.participant != name:
                why = f"{visible(name, 80)!r} sent a StepDone naming {visible(d.participant, 80)!r}"
            elif name not in self.participants:
                why = f"{visible(name, 80)!r} holds no participant token"
            elif name in self.gone:
                why = f"{visible(name, 80)!r}'s process has ended (its runner says so)"
            elif d.run != self.run:
                why = f"{visible(name, 80)!r} acknowledges run {visible(d.run, 80)!r}"
            elif d.resync:
                why = self._honour(name)
            elif published is None or d.stamp > published + EPSILON:
                why = f"{visible(name, 80)!r} acknowledges t={d.stamp:.3f}, not yet published"
            elif d.sent and min(d.sent.values()) < 0:
                why = f"{visible(name, 80)!r} counts fewer than no samples on a key"
            else:
                why = None
            if why is not None:
                self.dropped(why)
            if why is not None or d.resync:
                return
            if d.working:  # a sign of life, no answer: still computing the step waited on
                if name in self._waiting and d.stamp >= self._stamp - EPSILON:
                    self._working[name] = self._wall()
                return
            over = self.ledger.over_cap(name, d.sent, self.counts.sent.keys())
            if over is not None:  # its answer counts, its claims do not
                self.dropped(f"{visible(name, 80)!r}'s claims dropped: {visible(over, 80)}")
                if name not in self.ledger.capped and len(self.ledger.capped) < MAX_NAMES:
                    self.ledger.capped.add(name)
                    self.forgiven += 1  # not waited for: the run is inexact
                    self._tell = True
            far = d.next > d.stamp + NEXT_HORIZON
            if over is not None or far:  # far: stopped for again at least every NEXT_HORIZON s
                d = StepDone(d.participant, d.stamp, {} if over is not None else d.sent,
                             d.stamp + NEXT_HORIZON if far else d.next, d.run, d.forgiven)
            prev = self.done.get(name)
            if prev is not None and d.stamp < prev.stamp - EPSILON:
                return  # an older answer overtaken by a newer one
            self.ledger.answer(name, d)
            if d.forgiven > self._their_forgiven.get(name, 0) and \
                    (name in self._their_forgiven or len(self._their_forgiven) < MAX_NAMES):
                self._their_forgiven[name] = d.forgiven
                self._tell = True  # the next wait() publishes the status
            self._due_at = None
            if name in self.unresponsive and d.stamp >= published - EPSILON:
                # answers the current step again: waited for (and stopped for) from now on
                self.unresponsive.discard(name)
                self._back.add(name)
                self._cond.notify_all()
            elif name in self._waiting and d.stamp >= self._stamp - EPSILON:
                self._waiting.discard(name)
                if not self._waiting:  # the last answer: wait() looks at the counts
                    self._cond.notify_all()

    def _honour(self, name: str) -> str | None:
        """`name` asks for the current step with the whole table (it cannot follow the steps it
        heard): at the next physics step, or at once if a step is being waited on. One request
        per participant per REPORT_AFTER (a forger may ask in its name); None if honoured."""
        now = self._wall()
        if now - self._asked.get(name, now - REPORT_AFTER) < REPORT_AFTER:
            return f"{visible(name, 80)!r} asked for the whole table again within {REPORT_AFTER} s"
        self._asked[name] = now
        self._resync = self._republish = self._whole = True
        self._cond.notify_all()
        return None

    def _answered(self, name: str, stamp: float) -> bool:
        d = self.done.get(name)
        return d is not None and d.stamp >= stamp - EPSILON

    def sent(self) -> dict[str, int]:
        """What the next step requires: the simulator's own samples (sensor data: on the same
        link as the step, but Zenoh may run the callbacks of two subscriptions concurrently)
        and every participant's, cumulative counts per key."""
        own = self.counts.sent
        with self._cond:
            out = dict(self.ledger.claims)
        out.update(own)  # what it sent itself, it knows: nobody's claim on those counts
        return out

    def _poke(self) -> None:
        """A sample was counted: what wait() is after once every participant has answered
        (before that, an answer wakes it)."""
        with self._cond:
            if self._stamp is not None and not self._waiting:
                self._cond.notify_all()

    def due(self, stamp: float) -> bool:
        """Must the simulator stop at `stamp`? Yes if a participant has something to do by
        then (or has not said), asked for the whole table, or is given up and has not had it
        for REPORT_AFTER; the steps in between run without a round trip."""
        with self._cond:
            if self._resync or (self.unresponsive and self._wall() >= self._resend_at):
                return True
            if self._due_at is None:  # recomputed only after answers or the set changed
                due_at = float("inf")
                for p in self.participants:
                    if p in self.unresponsive or p in self.gone:
                        continue
                    d = self.done.get(p)
                    if d is None or d.next < 0:
                        due_at = float("-inf")
                        break
                    due_at = min(due_at, d.next)
                self._due_at = due_at
            return self._due_at <= stamp + EPSILON

    def claims(self, required: dict[str, int] | None = None) -> Claims:
        """`sent()` by index in the run's key table (new keys appended)."""
        required = self.sent() if required is None else required
        table = self.table
        table.add(required.keys())
        return Claims(table, list(map(required.get, table.keys, itertools.repeat(0))))

    def publish(self, stamp: float) -> None:
        self.step += 1
        required = self.sent()
        if len(self.table) + len(required.keys() - self.table.index.keys()) > MAX_KEYS:
            # keys of participants gone: a new table of the keys claimed now, sent whole (the
            # caps keep those within MAX_KEYS, ledger.py)
            self.table = KeyTable()
            with self._cond:
                self._whole = True
        counts = self.claims(required).packed()
        with self._cond:
            now = self._wall()
            if self.unresponsive and now >= self._resend_at:
                self._resend_at = now + REPORT_AFTER  # those given up get the whole table
                self._whole = True
            base = 0 if self._whole or self._last is None else count_of(self._last)
            table = self.table
            step = Step(stamp, self.step, counts, table.keys[base:], base, table.digest,
                        self.run, self.timeout)
            self._last, self._republish, self._whole, self._resync = step, False, False, False
        self.bus.publish(STEP, step)

    def _whole_step(self, step: Step) -> Step:
        """`step` with the whole table it counts by (for a newcomer, or one that missed keys)."""
        if step.base == 0:
            return step
        return msgspec.structs.replace(step, keys=self.table.keys[:count_of(step)], base=0)

    def wait(self, stamp: float, stop: threading.Event) -> None:
        """Until every participant is done with `stamp` and its commands of that step have been
        taken into account here (the counts in its StepDone; Zenoh may run two subscriptions'
        callbacks out of order) — or the participant is given up for this time; it rejoins
        when it answers again. Claims that cannot be met are forgiven (Books), never waited
        for beyond count_wait."""
        start = self._wall()
        deadline = start + self.timeout
        self._report_at = start + min(REPORT_AFTER, self.timeout)
        answered_at: float | None = None  # when the last participant answered
        report = False  # a change for lockstep/status
        with self._cond:
            self._stamp = stamp
            self._waiting = {p for p in self.participants if p not in self.unresponsive
                             and p not in self.gone and not self._answered(p, stamp)}
            self._working, self._told_working = {}, set()
        try:
            report = self._wait(stamp, stop, deadline, answered_at, report)
        finally:
            with self._cond:
                self._stamp, self._waiting, self._working = None, set(), {}
                report, self._tell = report or self._tell, False
                outlived = self._outlived()
        if report:
            self._status(stamp)
        if outlived:
            self._tell_outlived(stamp)

    def _tell_outlived(self, stamp: float) -> None:
        self.bus.publish(refused_key(self.name), tally(Header(self.name, stamp, 0), {
            ("participant", name, OUTLIVED, True): 1 for name in sorted(self.outlived)}))

    def _outlived(self, final: bool = False) -> bool:
        """Whether another ended member's token has outlived its process by OUTLIVED_AFTER
        (`__init__`), or is still there as the barrier closes (`final`): it is counted. Under
        self._cond."""
        now = self._wall()
        new = {p for p, at in self.gone.items() if p not in self.outlived
               and p in self.participants and (final or now - at >= OUTLIVED_AFTER)}
        self.outlived |= new
        return bool(new)

    def _wait(self, stamp: float, stop: threading.Event, deadline: float,
              answered_at: float | None, report: bool) -> bool:
        while not stop.is_set():
            with self._cond:
                step, republish = self._last, self._republish
                self._republish = False
                if republish:
                    self._resync = False  # the request is answered by this one
            if republish and step is not None:
                self.bus.publish(STEP, self._whole_step(step))
            with self._cond:
                now = self._wall()
                waiting = self._waiting  # (kept up to date by _on_done, under this lock)
                back, self._back = self._back, set()
                if back:
                    report = True
                    log.warning("lockstep: %s answers again",
                                ", ".join(visible(p, 80) for p in sorted(back)))
                required = self.claims()
                self.books.review(required)
                missing = self.books.missing(required)
                if not waiting and answered_at is None:
                    answered_at = now
                if not waiting and not missing:
                    self.books.settle(required)
                    break
                late = answered_at is not None and \
                    now - answered_at >= count_wait(self.timeout)
                forgive = missing if late or now >= deadline else self.books.at_once(missing)
                if forgive:
                    if self.books.forgive(forgive, required):  # a claimant's first, in a window
                        self.forgiven += 1
                        report = True
                    self.dropped(f"claims of {sum(forgive.values())} samples on "
                                 f"{', '.join(visible(k, 80) for k in sorted(forgive)[:3])} that "
                                 f"did not arrive by t={stamp:.2f}: forgiven")
                    continue
                if waiting and now >= self._report_at < deadline:
                    self._report_at = deadline  # once per step
                    self._republish = True  # with the whole key table: it may have missed keys
                    log.warning("lockstep: %s did not finish t=%.2f within %.1f s; still waited "
                                "for while it holds its participant token (given up after "
                                "%.1f s without an answer or a sign of work)",
                                ", ".join(visible(p, 80) for p in sorted(waiting)),
                                stamp, REPORT_AFTER, self.timeout)
                if waiting and now >= deadline - self.timeout + ENDED_AFTER and \
                        self._ended(waiting):
                    continue
                if self.unresponsive and now >= self._resend_at:
                    # one given up may be passing steps over for want of the table (it left
                    # the waiting set, so the lines above no longer reach it)
                    self._resend_at = now + REPORT_AFTER
                    self._republish = True
                if now >= deadline:
                    hung = self._hung(waiting, now, deadline)
                    if hung:
                        self._waiting = waiting - hung
                        self.unresponsive |= hung
                        self.given_up += len(hung)
                        self._due_at = None
                        log.warning("lockstep: %s did not finish t=%.2f within %.1f s: no "
                                    "longer waited for",
                                    ", ".join(visible(p, 80) for p in sorted(hung)),
                                    stamp, now - deadline + self.timeout)
                        report = True
                        if not self._waiting:
                            break
                        continue
                self._cond.wait(0.05 if now >= deadline else min(deadline - now, 0.05))
        return report

    def _ended(self, waiting: set[str]) -> bool:
        """Whether some of `waiting` have ended (`ended`, __init__): no longer waited for. Under
        self._cond; the file is read at most every ENDED_AFTER of wall time."""
        now = self._wall()
        if self.ended is None or now < self._ended_read + ENDED_AFTER:
            return False
        self._ended_read = now
        gone = waiting & self.ended()
        if not gone:
            return False
        self.gone.update(dict.fromkeys(gone, now))
        self._waiting = waiting - gone
        self._due_at = None
        for name in sorted(gone):
            self.dropped(f"{visible(name, 80)!r}'s participant token outlives its process (a "
                         "token under its name from another session): not waited for")
        self._cond.notify_all()
        return True

    def _hung(self, waiting: set[str], now: float, deadline: float) -> set[str]:
        """Those of `waiting` to give up at `now`, past the step's deadline: silent — neither
        an answer nor a work beat (StepDone `working`: its loop is computing) — for the
        timeout, or waited for WORK_LIMIT timeouts however they beat (a computation that never
        ends, or a forger beating in a stuck participant's name). Those still computing are
        said once per step. Under self._cond."""
        start = deadline - self.timeout
        hung = {p for p in waiting if now - self._working.get(p, start) >= self.timeout
                or now - start >= WORK_LIMIT * self.timeout}
        busy = sorted(set(waiting) - hung - self._told_working)
        if busy:
            self._told_working.update(busy)
            log.warning("lockstep: %s still computing t=%.2f after %.1f s (its loop thread "
                        "uses CPU time): waited for, at most %.0f s",
                        ", ".join(visible(p, 80) for p in busy), self._stamp,
                        now - start, WORK_LIMIT * self.timeout)
        return hung

    def _status(self, stamp: float) -> None:
        with self._cond:
            status = LockstepStatus(stamp, tuple(sorted(self.unresponsive)), self.dropped.count,
                                    tuple(sorted(self.rivals)), self.given_up,
                                    self.forgiven + sum(self._their_forgiven.values()))
        self.bus.publish(STATUS, status)

    def close(self) -> None:
        """Withdraw the barrier's token and subscriptions — once a token that still lives under
        an ended member's name has had OUTLIVED_AFTER (real seconds, at most) to go: one that
        does not is counted (`__init__`; a run may end sooner than its check in wait())."""
        with self._cond:
            for _ in range(int(OUTLIVED_AFTER / 0.05)):
                if not any(p in self.participants for p in self.gone.keys() - self.outlived):
                    break
                self._cond.wait(0.05)
            outlived = self._outlived(final=True)
            stamp = self._last.stamp if self._last is not None else 0.0
        if outlived:
            self._tell_outlived(stamp)
        for h in self.handles:
            h.close()
        self.counts.close()

