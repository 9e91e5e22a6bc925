"""Lockstep simulation time: the simulator advances only when every participant has finished
its work for the current simulated time (Gazebo's lockstep; ROS `use_sim_time` with a
synchronous clock). A run's outcome then depends on the seed only, not on how busy the machine
is or how fast the simulator is allowed to go.

The protocol (docs/architecture.md, "lockstep"):

* A participant (an agent on `--sim-time`) holds the liveliness token
  `@mrta/lockstep/participant/<id>`; the simulator waits for exactly those. A token gone (the
  process died) is no longer waited for. An `@` key is matched by no wildcard, so observers
  (`echo '**'`, the recorder) neither see lockstep traffic nor take part in it.
* After each physics step — sensor data published first, on the same link — the simulator
  publishes `Step(stamp, step, counts, keys, base, table_digest)` reliably on
  `@mrta/lockstep/step`: cumulative counts per key, by index in the run's key table
  (`KeyTable`), of which it carries only the keys new since the previous step — the whole
  table to a newcomer, to a participant silent for REPORT_AFTER (one that missed keys), and
  every REPORT_AFTER while one is given up; past MAX_KEYS keys a new table, sent whole.
* A participant's time moves to `stamp` only once it has received every sample the other
  participants had published before their last acknowledgement (the counts, for the keys it
  subscribes to). That is what makes a broadcast from robot A, sent while
  A handled step k, reach robot B before B handles step k+1, whatever the network's scheduling.
* When the participant has nothing more to do at that time — its main loop would wait for a
  later time — it publishes `StepDone(participant, stamp, sent, next)` on
  `@mrta/lockstep/done/<id>`: its commands of that step went out before it, on the same link,
  and `next` is the time it waits for. The simulator stops only at steps where some
  participant has something due (an agent at 10 Hz: every fifth 20 ms step), so lockstep costs
  one round trip per participant tick, not per physics step.
* The simulator steps again once every participant is done and it has taken their commands
  of that step into account (counted as for the participants). A participant silent for
  `REPORT_AFTER` (2.5 s: below the 3 s Zenoh lease, so a stopped process is reported before its
  token expires) is reported in the log and still waited for while it holds its participant
  token — a slow participant on a busy machine must not change what the run does. One silent
  for `timeout` wall seconds (30 s by default) with its token alive is given up (a log line
  and `lockstep/status`, which the supervisor shows as an alarm) until it answers again; the
  status counts give-ups and forgiven claims, and a mission's summary calls such a run inexact.

Trust (docs/security.md, "Lockstep and the clock"). Exact checks — they hold against anybody
who cannot declare our tokens (a secured fleet) and against blind forgers on an open bus:
* a Step counts only if its `run` holds `@mrta/lockstep/barrier/<run>`; a participant follows
  one run at a time, and another run is taken only once the first one's token is gone (a second
  lockstep simulator is reported, not followed);
* step numbers only grow within a run; a step behind the participant's time is rejected;
* a StepDone counts only from a name that holds its participant token, under its own key, for
  this run, for a step already published (never "done" in advance); its `next` is clamped to
  `NEXT_HORIZON` seconds ahead, so no claim can excuse a participant for long;
* a run that ends (its barrier token is gone) restarts the participant's counts, sent and
  received, and a new run its time.
Heuristics — plausibility against an attacker on an open bus who copies run ids and names:
* a step stops at or before a participant's own `next` plus one physics step (`STEP_SLACK`):
  a later one is taken only as far as wall time allows since the participant was last heard
  (a `StepBudget` at the run's announced speed, mrta_zenoh.clock.run_rate) — that is how a
  participant that was stopped, and given up, rejoins the current step;
* counts: a claim more than `MAX_IN_FLIGHT` samples beyond what arrived is dropped at once; a
  smaller one that is not met within `count_wait(timeout)` is forgiven (`Books`: the samples were
  lost, e.g. while a stopped peer's link was down) — counted and logged, never waited for again;
  a later, lower claim for the same key withdraws a forgiveness (legitimate counts only grow
  within a run, so the forgiven one was forged).
The barrier also re-publishes the step it waits on when a participant (re)appears, so a
resumed or late participant answers at once instead of after the timeout.
"""

from __future__ import annotations

import contextlib
import itertools
import logging
import operator
import sys
import threading
import time
from array import array
from typing import Callable

import msgspec
# hashlib's own BLAKE2b, without hashlib: importing hashlib loads OpenSSL (_hashlib) into every
# agent (tests/test_agent_imports.py)
from _blake2 import blake2b

from .clock import CEILING, EPSILON, SimClock, _printable, run_rate
from .keys import CLOCK_SOURCE_TOKEN, matches
from .messages import Finite, Message, message

log = logging.getLogger("mrta.lockstep")

STEP = "@mrta/lockstep/step"
DONE = "@mrta/lockstep/done"           # /<participant>
PARTICIPANT = "@mrta/lockstep/participant"  # /<participant>: liveliness
BARRIER = "@mrta/lockstep/barrier"      # /<run>: liveliness of a lockstep simulator
STATUS = "lockstep/status"

# A participant silent this long (wall s) is given up — but only a live one reaches it: a dead or
# stopped process loses its participant token with its session (at once, or after the 3 s Zenoh
# lease, mrta_zenoh/bus/options.py), and a participant without a token is not waited for. A
# slow one — a busy machine, a CPU-starved process — holds its token and is waited for: giving it
# up would make the run depend on the machine's load, which is what lockstep is there to stop.
DEFAULT_TIMEOUT = 30.0
REPORT_AFTER = 2.5      # wall s: a participant silent this long is reported (still waited for)
STEP_SLACK = 0.05       # simulated s past a participant's `next` a step may stop (one 20 ms step)
STEP_BURST = 1.0        # simulated s a step may jump beyond that without wall time to show for it
NEXT_HORIZON = 10.0     # simulated s: the longest `next` a StepDone may announce
MAX_IN_FLIGHT = 10_000  # samples a claim may be ahead of what arrived and still be waited for
MAX_KEYS = 4096         # keys a Step or StepDone may count
MAX_NAMES = 1024        # participants and runs remembered (a flood of tokens costs bounded memory)
LOG_FIRST = 5           # rejected samples logged one by one; then one line per LOG_EVERY


def count_wait(timeout: float) -> float:
    """How long counts that do not arrive are waited for before they are forgiven: half the
    barrier's timeout (so a participant still answers in time), at most 5 s — long enough for
    a CPU-starved process to deliver what it received (forgiving legitimate counts makes a run
    inexact), short enough that a forged claim costs one 5 s pause, once (docs/security.md)."""
    return min(5.0, max(0.05, timeout / 2))


@message("mrta_msgs/Step")
class Step(Message):
    """`counts`: samples sent on the run's i-th key (`KeyTable`) before this step, for every
    key of the table, packed as unsigned 64-bit little-endian words (word i: key i) — a
    participant finds the words that changed since the step it last took in C (`Books`);
    `keys`: the table's keys from index `base` on — those new since the previous step, or all
    of them (`base` 0) for a newcomer; `table_digest`: the whole table's (a participant whose
    table differs waits for a whole one)."""

    stamp: Finite
    step: int
    counts: bytes
    keys: list[str] = []
    base: int = 0
    table_digest: bytes = b""
    run: str = ""                     # the simulator's run id (its barrier and clock tokens)
    timeout: Finite = DEFAULT_TIMEOUT  # the barrier's, wall seconds: participants' count_wait


@message("mrta_msgs/StepDone")
class StepDone(Message):
    """Done with `stamp`; nothing to do before `next` (-1: unknown), so the simulator need not
    stop for this participant at the steps in between."""

    participant: str
    stamp: Finite
    sent: dict[str, int]
    next: Finite = -1.0
    run: str = ""  # the run whose step this acknowledges
    forgiven: int = 0  # claims this participant forgave in this run: the run is then inexact


@message("mrta_msgs/LockstepStatus")
class LockstepStatus(Message):
    """Participants the simulator stopped waiting for (alive, but silent past the timeout);
    `dropped`: StepDones and claims it refused (non-participants, implausible counts);
    `rivals`: other clock sources or lockstep runs on the bus (one source per run);
    `given_up` / `forgiven`: how often, in this run, a participant was given up and a claim
    forgiven — either makes the run inexact (it then depended on the machine), which a
    mission's summary says (`lockstep_exact`)."""

    stamp: Finite
    unresponsive: tuple[str, ...]
    dropped: int = 0
    rivals: tuple[str, ...] = ()
    given_up: int = 0
    forgiven: int = 0


class _Rejections:
    """Counted, and logged without flooding: the first few one by one, then one in LOG_EVERY."""

    LOG_EVERY = 1000

    def __init__(self, what: str) -> None:
        self.what = what
        self.count = 0

    def __call__(self, why: str) -> None:
        self.count += 1
        if self.count <= LOG_FIRST or self.count % self.LOG_EVERY == 0:
            log.warning("lockstep: %s rejected (%d so far): %s", self.what, self.count, why)


class KeyTable:
    """The keys a run's claims count, in the order the simulator first claimed them.

    A Step carries its claims as counts by index in this table, and only the keys new since the
    previous step (issue #27: with 100 robots a Step named about 1,100 keys, and each of 100
    participants decoded every name at every step). The table only grows within a run (the
    simulator starts a new one, sent whole, when it passes MAX_KEYS); `digest` (BLAKE2b of the
    keys, each ended by a newline — a CRC would be forged by anybody) lets a participant check
    that its copy is the simulator's: one that missed a step, or took a forged one, passes steps
    over until a whole table comes — the simulator sends one to a newcomer, and to a
    participant silent for REPORT_AFTER or given up."""

    def __init__(self) -> None:
        self.keys: list[str] = []
        self.index: dict[str, int] = {}
        self._hash = blake2b(digest_size=16)
        self.digest = self._hash.digest()
        self.generation = 0  # changes when keys are replaced, not only appended (Books)

    def __len__(self) -> int:
        return len(self.keys)

    def add(self, keys) -> None:
        """The simulator's side: append those of `keys` the table does not have (sorted)."""
        self._append(sorted(keys - self.index.keys()))

    def _append(self, new: list[str], hashed=None) -> None:
        """Append `new`; `hashed`: the digest's state with them already in (take checked it)."""
        if hashed is None:
            if not new:
                return
            hashed = self._hash.copy()
            hashed.update(_joined(new))
        n = len(self.keys)
        self.keys.extend(new)
        self.index.update(zip(new, range(n, n + len(new))))
        self._hash, self.digest = hashed, hashed.digest()

    def take(self, step: "Step") -> str | None:
        """A participant's side: make this table the one `step` counts by. None: done; "":
        it cannot be known from this step (one carrying keys was missed, or this copy is not
        the simulator's) — a whole table will come; otherwise why the step is malformed."""
        base, keys, n = step.base, step.keys, len(self.keys)
        if len(step.counts) % WORD:
            return f"its counts are {len(step.counts)} bytes, not whole {WORD}-byte words"
        if base < 0 or count_of(step) != base + len(keys):
            return f"it has {count_of(step)} counts for {base} + {len(keys)} keys"
        if base > n:
            return ""
        if base < n:  # a whole table (a newcomer's) or part of one: compared with this copy
            keys = self.keys[:base] + keys
            if keys[:n] != self.keys:  # not the same table: this copy was not the simulator's
                return self._replace(keys, step.table_digest)
            keys = keys[n:]
        if not keys:
            return None if self.digest == step.table_digest else ""
        if len(set(keys)) != len(keys) or not self.index.keys().isdisjoint(keys):
            return "its keys repeat"
        hashed = self._hash.copy()
        hashed.update(_joined(keys))
        if hashed.digest() != step.table_digest:
            return ""
        self._append(keys, hashed)
        return None

    def _replace(self, keys: list[str], digest: bytes) -> str | None:
        if len(set(keys)) != len(keys):
            return "its keys repeat"
        hashed = blake2b(_joined(keys), digest_size=16)
        if hashed.digest() != digest:
            return ""
        self.keys, self.index = [], {}
        self._append(keys, hashed)
        self.generation += 1
        return None


def _joined(keys: list[str]) -> bytes:
    return "".join(k + "\n" for k in keys).encode()


WORD = 8  # bytes per count in a Step (unsigned 64-bit)


def count_of(step: Step) -> int:
    """How many counts a Step carries (KeyTable.take refuses one that is not whole words)."""
    return len(step.counts) // WORD


class Claims:
    """What a step requires, by key: `counts[i]` samples on the table's i-th key, as unsigned
    64-bit words (`array('Q')`, this machine's byte order). A step's counts cover its table:
    the table changes only when a step is taken (which then is the one pending) or when its run
    ends (emptied)."""

    __slots__ = ("table", "counts")

    def __init__(self, table: KeyTable, counts) -> None:
        self.table = table
        self.counts = counts if isinstance(counts, array) else array("Q", counts)

    @classmethod
    def of(cls, table: KeyTable, step: Step) -> "Claims":
        """A Step's claims (its counts are whole words: KeyTable.take checked them)."""
        counts = array("Q")
        counts.frombytes(step.counts)
        if sys.byteorder == "big":
            counts.byteswap()
        return cls(table, counts)

    def packed(self) -> bytes:
        """The counts as a Step carries them (little-endian words)."""
        if sys.byteorder == "big":
            swapped = array("Q", self.counts)
            swapped.byteswap()
            return swapped.tobytes()
        return self.counts.tobytes()

    def get(self, key: str) -> int | None:
        i = self.table.index.get(key)
        return None if i is None else self.counts[i]


_COUNTED, _IGNORED = b"\xff" * WORD, bytes(WORD)  # a table index's word in Books' mask


class Books:
    """What this process received of what the others say they sent, less what is known lost.

    Counts are cumulative per key. A sample that will never arrive (its link was down; a forged
    claim) would hold every later step for ever: `forgive` records it as an offset, so only the
    one step waits (at most count_wait), and the next ones count from there.

    Cost (issue #27). A step claims every key of the run — with 100 robots about 1,100 — and a
    participant looks at its claims once per step; most keys are none of its subscriptions',
    and of those that are (a teammate's broadcast, its log) few changed since the last step. A
    loop over its few hundred keys in Python was half of a patrol agent's CPU with 100 agents on
    2 cores (py-spy, GIL samples; caches are cold with 100 processes). So which subscriptions
    count a key is worked out once per key (again when the bus's subscriptions change), and
    which table indices each subscription counts once per table entry; claims and counts are
    then compared per subscription in C (`map` and `compress` over the lists' and dicts' own
    methods): Python sees only the keys that lag behind.

    And most steps need not even that: once a step is taken (`settle`), every claim it made
    has arrived or been forgiven, and within a run counts and offsets only grow — so at the
    next step only the claims that changed can lag. Which of this participant's keys changed is
    one XOR of the two steps' packed counts, masked by the words its subscriptions count (big
    integers: C over a few kB); Python then looks at those keys only (100 agents: a dozen or so
    a step, against a few hundred compared before). A withdrawn forgiveness lowers an offset,
    but only for a key whose claim went down, which is then among those that changed. Anything
    else that voids the argument — other subscriptions, another table, a new run — falls back
    to the comparison over every key."""

    MEMO = 4 * MAX_KEYS  # keys remembered; beyond, the memory starts again

    def __init__(self, bus) -> None:
        self.bus = bus
        self.offsets: dict[str, int] = {}
        self._forgiven: dict[str, tuple[int, int]] = {}  # key → (claim forgiven, offset before)
        self.lost = 0
        self._subs: tuple = ()                    # the counting subscriptions the memo is for
        self._matching: dict[str, tuple] = {}     # key → the counting subscriptions matching it
        self._unmatched: set[str] = set()         # keys of `_matching` no subscription counts
        self._table: KeyTable | None = None       # the table `_indices` is for …
        self._generation = -1                     # … in this generation
        self._learned = 0                         # … up to this entry
        self._indices: dict = {}                  # subscription → ([table index], [key])
        self._words = bytearray()                 # per table index: 8 × 0xff if counted
        self._mask = 0                            # … as one integer
        # the claims of the step last taken: (table, generation, subscriptions, counts)
        self._settled: tuple | None = None
        self._looked: tuple = ()                  # the subscriptions the last whole look was for

    def _counting(self, table: KeyTable | None = None) -> dict[str, tuple]:
        """key → matching counting subscriptions, valid for the bus's subscriptions now (and
        `_indices` for `table`)."""
        subs = self.bus.counting_subscriptions()
        if subs != self._subs or len(self._matching) > self.MEMO:
            self._subs = subs
            self._matching = {}
            self._unmatched = set()
            self._table = None
        if table is not None and (table is not self._table or
                                  table.generation != self._generation):
            self._table, self._generation, self._learned = table, table.generation, 0
            self._indices = {s: ([], []) for s in self._subs}
            self._words, self._mask = bytearray(), 0
        return self._matching

    def _subs_of(self, matching: dict[str, tuple], key: str) -> tuple:
        subs = matching.get(key)
        if subs is None:
            subs = matching[key] = tuple(s for s in self._subs if matches(s.key_expr, key))
            if not subs:
                self._unmatched.add(key)
        return subs

    def _received(self, matching: dict[str, tuple], key: str) -> int | None:
        """Samples on `key` every subscription of this bus matching it has taken into account
        (None: no subscription matches, nothing to wait for)."""
        subs = self._subs_of(matching, key)
        if not subs:
            return None
        return min(s.counts[key] for s in subs)

    def missing(self, required: Claims, keys=None) -> dict[str, int]:
        """Key → samples claimed that have not arrived (keys no subscription of this bus
        counts are never waited for). A key this bus publishes itself is waited for up to what
        it sent, heard back by its own subscriptions (a robot's ReportDue hearing its own
        report): were they handed over on another thread, the tick that first sees one would
        depend on thread scheduling — two runs of one seed ended robot3's report 0.1 s apart
        under load when Zenoh delivered them. ZenohBus now hands them over before publish()
        returns, so this wait is met at once there; it stays for a bus that does not (the
        Bus contract does not promise it). `keys`: look only at
        these (those found missing before: counts only grow, so the others still have
        arrived)."""
        own = self.bus.sent_counts
        matching = self._counting(required.table)
        if keys is None:
            keys = self._lagging(matching, required, own)
        offsets = self.offsets
        out = {}
        for key in keys:
            got = self._received(matching, key)
            need = own[key] if key in own else required.get(key)
            if got is None or need is None:
                continue
            gap = need - got - offsets.get(key, 0)
            if gap > 0:
                out[key] = gap
        return out

    def _lagging(self, matching: dict[str, tuple], required: Claims,
                 own: dict[str, int]) -> set[str]:
        """The keys that may lag: those some subscription has counted less of (plus its
        offset) than claimed, found per subscription in C, and every key this bus sent that a
        subscription of its own counts (its claim is what it sent: `missing` decides those one
        by one). A superset of what is missing."""
        table = required.table
        self._looked = self._subs
        if self._learned < len(table):
            words = self._words
            for i in range(self._learned, len(table)):
                key = table.keys[i]
                subs = self._subs_of(matching, key)
                words += _COUNTED if subs else _IGNORED
                for s in subs:
                    indices, keys = self._indices[s]
                    indices.append(i)
                    keys.append(key)
            self._learned = len(table)
            self._mask = int.from_bytes(words, "little")
        if not own.keys() <= matching.keys():  # in C
            for key in own.keys() - matching.keys():
                self._subs_of(matching, key)
        zeros = itertools.repeat(0)
        counts, offsets = required.counts, self.offsets
        out = set(own.keys() - self._unmatched)
        settled = self._settled
        if settled is not None and settled[0] is table and settled[1] == table.generation \
                and settled[2] is self._subs and len(settled[3]) <= len(counts):
            changed = (int.from_bytes(counts, "little") ^
                       int.from_bytes(settled[3], "little")) & self._mask
            if changed:
                words = array("Q")
                words.frombytes(changed.to_bytes(len(counts) * WORD, "little"))
                keys = table.keys
                for i in itertools.compress(range(len(words)), words):
                    key = keys[i]
                    claim = counts[i] - offsets.get(key, 0)
                    if any(claim > s.counts.get(key, 0) for s in matching[key]):
                        out.add(key)
            return out
        for sub, (indices, keys) in self._indices.items():
            claimed = map(counts.__getitem__, indices)
            counted = map(sub.counts.get, keys, zeros)
            if offsets:
                counted = map(operator.add, counted, map(offsets.get, keys, zeros))
            out.update(itertools.compress(keys, map(operator.gt, claimed, counted)))
        return out

    def settle(self, taken: Claims) -> None:
        """`taken`'s claims have all arrived or been forgiven (its step was taken): the next
        look compares with them (only what changed since can lag)."""
        self._settled = (taken.table, taken.table.generation, self._looked, taken.counts)

    def forgive(self, missing: dict[str, int], required: Claims) -> None:
        for key, gap in missing.items():
            before = self.offsets.get(key, 0)
            claim = required.get(key)
            if claim is not None:  # not so a key of its own nobody claimed: no claim to review
                self._forgiven[key] = (claim, before)
            self.offsets[key] = before + gap
            self.lost += gap

    def review(self, required: Claims) -> list[str]:
        """Withdraw forgiveness a later, lower claim shows to have been forged (legitimate counts
        only grow within a run); the keys it was withdrawn for."""
        withdrawn = []
        for key, (claim, before) in list(self._forgiven.items()):
            now = required.get(key)
            if now is not None and now < claim:
                self.offsets[key] = before
                del self._forgiven[key]
                withdrawn.append(key)
        return withdrawn

    def reset(self) -> None:
        """A new run: counts start again from zero, sent and received."""
        self.bus.reset_counts()
        self.offsets.clear()
        self._forgiven.clear()
        self._settled = None


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


class LockstepClock(SimClock):
    """A participant's clock: simulation time that also moves in lockstep when the simulator
    runs it (and follows the plain `clock` key otherwise)."""

    def __init__(self, participant: str, wall=time.monotonic) -> None:
        super().__init__(wall=wall)
        self.participant = participant
        self.lockstep = threading.Event()
        self.run: str | None = None           # the lockstep run whose steps move time
        self.rejected_steps = _Rejections(f"step for {_printable(participant)}")
        self.step_rivals: set[str] = set()
        self._bus = None
        self._books: Books | None = None
        self._table = KeyTable()              # the run's keys, as its steps name them
        self.table_waits = 0                  # steps passed over while waiting for a whole table
        self._barriers: set[str] = set()      # runs whose barrier token lives
        self._step_no = 0
        self._step_budget = StepBudget(CEILING, wall)
        self._pending: Step | None = None
        self._claims: Claims | None = None    # the pending step's
        self._pending_wall = 0.0
        # the pending step's keys found missing at the last look (None: look at all of them):
        # each sample received while a step is pending looks again, at these only (issue #27)
        self._still_missing: list[str] | None = None
        self._new_run = False                 # the pending step opens a new run
        self._refused: Step | None = None     # a new run's step refused while the old one lives
        self._timer: threading.Timer | None = None  # looks at a pending step's counts again
        self._acked = True
        self._sleeping_until: float | None = None  # the main loop waits for this time
        self._publish_done: Callable[[float, float], None] | None = None
        self.forgiven = 0  # claims forgiven in this run (a new run starts again)

    def in_lockstep(self) -> bool:
        return self.lockstep.is_set()

    def join(self, bus) -> contextlib.ExitStack:
        """Count traffic, follow steps, and announce the participant; returns the handles as
        one ExitStack (closing it leaves the barrier)."""
        self._bus = bus
        self._books = Books(bus)
        bus.counting = True
        done_key = f"{DONE}/{self.participant}"

        def publish_done(stamp: float, next_due: float) -> None:
            bus.publish(done_key, StepDone(self.participant, stamp, dict(bus.sent_counts),
                                           next_due, self.run or "", self.forgiven))

        self._publish_done = publish_done
        handles = [bus.watch_liveliness(f"{BARRIER}/*", self._on_barrier),
                   bus.subscribe(STEP, self._on_step, msg_type=Step)]
        # while steps are pending, every received sample may be the one they wait for
        bus.on_counted = self._release
        handles.append(bus.declare_token(f"{PARTICIPANT}/{self.participant}"))
        stack = contextlib.ExitStack()
        for h in handles:
            stack.callback(h.close)
        return stack

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
        with self._cond:
            why = self._judge(step)
            if why == "":
                return  # the step again (re-published for a newcomer): nothing new
            if why is not None:
                self.rejected_steps(why)
                return
            self.lockstep.set()
            self._pending = step
            self._claims = Claims.of(self._table, step)
            self._pending_wall = self._wall()
            self._still_missing = None
        self._release()

    def _judge(self, step: Step) -> str | None:
        """None: take it; "": a duplicate; otherwise why it is refused. Under self._cond."""
        if count_of(step) > MAX_KEYS:
            return f"it counts {count_of(step)} keys (at most {MAX_KEYS})"
        if step.run != self.run:
            if step.run not in self._barriers:
                return f"run {_printable(step.run)!r} holds no barrier token"
            if self.run is not None and self.run in self._barriers:
                if step.run not in self.step_rivals and len(self.step_rivals) < MAX_NAMES:
                    self.step_rivals.add(step.run)
                    log.warning("lockstep: a second lockstep run %r while %r runs: ignored",
                                _printable(step.run), _printable(self.run))
                self._refused = step
                return f"run {_printable(step.run)!r} while {_printable(self.run)!r} runs"
            table = KeyTable()
            why = self._take_table(table, step)
            if why is not None:
                return why
            self.run, self._step_no, self._new_run = step.run, step.step, True
            self._table = table
            self._step_budget = StepBudget(run_rate(step.run) or CEILING, self._wall)
            return None
        pending = self._pending
        if step.step <= self._step_no:
            if step.step == self._step_no and (pending is None or pending.step == step.step):
                return ""
            return f"step {step.step} after step {self._step_no}"
        if step.stamp < self._now - EPSILON:
            return f"t={step.stamp:.3f} is behind this participant's t={self._now:.3f}"
        self._step_budget.refill()
        due = self._sleeping_until if self._sleeping_until is not None else self._now
        beyond = step.stamp - (max(due, self._now) + STEP_SLACK)
        if beyond > EPSILON and not self._step_budget.affords(beyond):
            return (f"t={step.stamp:.3f} is beyond this participant's next (t={due:.3f}) by "
                    f"more than wall time allows")
        why = self._take_table(self._table, step)  # a step passed over spends no budget
        if why is None:
            if beyond > EPSILON:
                self._step_budget.spend(beyond)
            self._step_no = step.step
        return why

    def _take_table(self, table: KeyTable, step: Step) -> str | None:
        """The step's keys into `table` (KeyTable.take); a step that cannot be known yet is
        passed over quietly (counted): a whole table comes to a newcomer, to a participant
        silent for REPORT_AFTER and to one given up — the step itself again, which it then
        takes."""
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
                huge = any(gap > MAX_IN_FLIGHT for gap in missing.values())
                left = count_wait(step.timeout) - (self._wall() - self._pending_wall)
                if not huge and left > 0:
                    if self._timer is None:  # look again then, even if nothing arrives
                        self._timer = threading.Timer(left + 0.01, self._recheck)
                        self._timer.daemon = True
                        self._timer.start()
                    return
                books.forgive(missing, claims)
                self.forgiven += 1  # told to the simulator in every StepDone (LockstepStatus)
                log.warning("lockstep: %s: %d samples on %s never arrived by t=%.2f: forgiven",
                            _printable(self.participant), sum(missing.values()),
                            ", ".join(_printable(k) for k in sorted(missing)[:3]), step.stamp)
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
                                "t=%.3f)", _printable(step.run), step.stamp,
                                _printable(self.source), self._now)
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


class Barrier:
    """The simulator's side: whom to wait for, and waiting. A context manager: leaving it
    withdraws the barrier's token and subscriptions (close()).

    Cost per step (issue #27: 100 participants answering every step): an answer updates who
    is still waited for, the per-key claims and the due cache in O(its own keys); only the
    last answer (then the counts it waits for) wakes wait(). Before, every answer and every
    counted sample woke it and each wake rescanned every participant's StepDone."""

    def __init__(self, bus, run_id: str, timeout: float = DEFAULT_TIMEOUT,
                 wall=time.monotonic):
        self.bus = bus
        self.run = run_id
        self.timeout = timeout
        self.participants: set[str] = set()
        self.done: dict[str, StepDone] = {}
        self.unresponsive: set[str] = set()
        self.rivals: set[str] = set()
        self.given_up = 0   # participants given up, this run (LockstepStatus)
        self.forgiven = 0   # claims forgiven, this run
        self._report_at = 0.0  # wall time wait() reports the participants still silent
        self._their_forgiven: dict[str, int] = {}  # participant → claims it forgave (StepDone)
        self._tell = False  # a participant forgave more: publish the status
        self.books = Books(bus)
        self.table = KeyTable()  # the run's keys, as its steps name them
        self._whole = True       # the next step carries the whole table (a newcomer appeared)
        self._resend_at = 0.0    # wall time the whole table goes again to those given up
        self.dropped = _Rejections("StepDone")
        self._wall = wall
        self._cond = threading.Condition()
        self._changed, self._changed_at = 0, wall()
        self._last: Step | None = None  # the step published last (re-published for newcomers)
        self._republish = False
        self._back: set[str] = set()  # given up, and answering again
        # Kept up to date as StepDones arrive, so a step costs one look per answer, not a scan
        # of every participant per answer (issue #27: 100 participants answering every step)
        self._stamp: float | None = None  # the step wait() is waiting on
        self._waiting: set[str] = set()   # participants it still waits for
        self._claims: dict[str, int] = {}  # key → the largest count in `done`
        self._due_at: float | None = None  # due() before this stamp is False (None: unknown)
        bus.counting = True  # set before the commands' subscription (SimNode) exists
        bus.on_counted = self._poke
        self.handles = [
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

    def _on_participant(self, key: str, alive: bool) -> None:
        name = key.rsplit("/", 1)[-1]
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
                            not self._answered(name, self._stamp):
                        self._waiting.add(name)
            else:
                self.participants.discard(name)
                self._waiting.discard(name)
                gone = self.done.pop(name, None)
                if gone is not None:
                    self._recount(k for k, n in gone.sent.items() if self._claims.get(k) == n)
                self.unresponsive.discard(name)
            self._cond.notify_all()

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
                    _printable(run), _printable(self.run))
        self._status(stamp)

    def _on_done(self, sample) -> None:
        d: StepDone = sample.message
        name = sample.key.rsplit("/", 1)[-1]
        with self._cond:
            published = self._last.stamp if self._last is not None else None
            if d.participant != name:
                why = f"{_printable(name)!r} sent a StepDone naming {_printable(d.participant)!r}"
            elif name not in self.participants:
                why = f"{_printable(name)!r} holds no participant token"
            elif d.run != self.run:
                why = f"{_printable(name)!r} acknowledges run {_printable(d.run)!r}"
            elif published is None or d.stamp > published + EPSILON:
                why = f"{_printable(name)!r} acknowledges t={d.stamp:.3f}, not yet published"
            elif len(d.sent) > MAX_KEYS:
                why = f"{_printable(name)!r} counts {len(d.sent)} keys"
            elif d.sent and min(d.sent.values()) < 0:
                why = f"{_printable(name)!r} counts fewer than no samples on a key"
            else:
                why = None
            if why is not None:
                self.dropped(why)
                return
            if d.next < 0 or d.next > d.stamp + NEXT_HORIZON:
                # unknown or far: the barrier stops for it again at least every NEXT_HORIZON s
                d = StepDone(d.participant, d.stamp, d.sent, d.stamp + NEXT_HORIZON
                             if d.next >= 0 else d.next, d.run, d.forgiven)
            prev = self.done.get(name)
            if prev is not None and d.stamp < prev.stamp - EPSILON:
                return  # an older answer overtaken by a newer one
            self.done[name] = d
            if d.forgiven > self._their_forgiven.get(name, 0) and \
                    (name in self._their_forgiven or len(self._their_forgiven) < MAX_NAMES):
                self._their_forgiven[name] = d.forgiven
                self._tell = True  # the next wait() publishes the status
            self._claim(prev, d)
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

    def _answered(self, name: str, stamp: float) -> bool:
        d = self.done.get(name)
        return d is not None and d.stamp >= stamp - EPSILON

    def _claim(self, prev: StepDone | None, d: StepDone) -> None:
        """Keep `_claims` the per-key maximum over `done` after `prev` became `d` (counts only
        grow in an honest run; a lower one may take the maximum down: those keys are counted
        again over every participant)."""
        claims, lowered = self._claims, []
        old = prev.sent if prev is not None else {}
        for k, n in d.sent.items():
            top = claims.get(k)
            if top is None or n > top:
                claims[k] = n
            elif n < top and old.get(k) == top:
                lowered.append(k)
        if old:
            lowered.extend(k for k in old.keys() - d.sent.keys() if claims.get(k) == old[k])
        if lowered:
            self._recount(lowered)

    def _recount(self, keys) -> None:
        for k in list(keys):
            counts = [d.sent[k] for d in self.done.values() if k in d.sent]
            if counts:
                self._claims[k] = max(counts)
            else:
                self._claims.pop(k, None)

    def sent(self) -> dict[str, int]:
        """What the next step requires: the simulator's own samples (sensor data: on the same
        link as the step, but Zenoh may run the callbacks of two subscriptions concurrently)
        and every participant's, cumulative counts per key."""
        out: dict[str, int] = dict(self.bus.sent_counts)
        with self._cond:
            for k, n in self._claims.items():
                if n > out.get(k, 0) or k not in out:
                    out[k] = n
        return out

    def _poke(self) -> None:
        """A sample was counted: what wait() is after once every participant has answered
        (before that, an answer wakes it)."""
        with self._cond:
            if self._stamp is not None and not self._waiting:
                self._cond.notify_all()

    def due(self, stamp: float) -> bool:
        """Must the simulator stop at `stamp`? Yes if a participant has something to do by
        then (or has not said); the steps in between run without a round trip."""
        with self._cond:
            if self._due_at is None:  # recomputed only after answers or the set changed
                due_at = float("inf")
                for p in self.participants:
                    if p in self.unresponsive:
                        continue
                    d = self.done.get(p)
                    if d is None or d.next < 0:
                        due_at = float("-inf")
                        break
                    due_at = min(due_at, d.next)
                self._due_at = due_at
            return self._due_at <= stamp + EPSILON

    def claims(self) -> Claims:
        """`sent()` by index in the run's key table (new keys appended)."""
        required = self.sent()
        table = self.table
        table.add(required.keys())
        return Claims(table, list(map(required.get, table.keys, itertools.repeat(0))))

    def publish(self, stamp: float) -> None:
        self.step += 1
        if len(self.table) > MAX_KEYS:  # keys of participants gone (one that forged thousands):
            self.table = KeyTable()     # a new table of the keys claimed now, sent whole
            with self._cond:
                self._whole = True
        counts = self.claims().packed()
        with self._cond:
            base = 0 if self._whole or self._last is None else count_of(self._last)
            table = self.table
            step = Step(stamp, self.step, counts, table.keys[base:], base, table.digest,
                        self.run, self.timeout)
            self._last, self._republish, self._whole = step, False, False
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
            self._waiting = {p for p in self.participants
                             if p not in self.unresponsive and not self._answered(p, stamp)}
        try:
            report = self._wait(stamp, stop, deadline, answered_at, report)
        finally:
            with self._cond:
                self._stamp, self._waiting = None, set()
                report, self._tell = report or self._tell, False
        if report:
            self._status(stamp)

    def _wait(self, stamp: float, stop: threading.Event, deadline: float,
              answered_at: float | None, report: bool) -> bool:
        while not stop.is_set():
            with self._cond:
                step, republish = self._last, self._republish
                self._republish = False
            if republish and step is not None:
                self.bus.publish(STEP, self._whole_step(step))
            with self._cond:
                now = self._wall()
                waiting = self._waiting  # (kept up to date by _on_done, under this lock)
                back, self._back = self._back, set()
                if back:
                    report = True
                    log.warning("lockstep: %s answers again",
                                ", ".join(_printable(p) for p in sorted(back)))
                required = self.claims()
                self.books.review(required)
                missing = self.books.missing(required)
                if not waiting and answered_at is None:
                    answered_at = now
                if not waiting and not missing:
                    self.books.settle(required)
                    break
                huge = {k: n for k, n in missing.items() if n > MAX_IN_FLIGHT}
                late = answered_at is not None and \
                    now - answered_at >= count_wait(self.timeout)
                if huge or (missing and (late or now >= deadline)):
                    forgive = missing if late or now >= deadline else huge
                    self.books.forgive(forgive, required)
                    self.forgiven += 1
                    self.dropped(f"claims of {sum(forgive.values())} samples on "
                                 f"{', '.join(_printable(k) for k in sorted(forgive)[:3])} that "
                                 f"did not arrive by t={stamp:.2f}: forgiven")
                    report = True
                    continue
                if waiting and now >= self._report_at < deadline:
                    self._report_at = deadline  # once per step
                    self._republish = True  # with the whole key table: it may have missed keys
                    log.warning("lockstep: %s did not finish t=%.2f within %.1f s; still waited "
                                "for while it holds its participant token (given up after "
                                "%.1f s)", ", ".join(_printable(p) for p in sorted(waiting)),
                                stamp, REPORT_AFTER, self.timeout)
                if self.unresponsive and now >= self._resend_at:
                    # one given up may be passing steps over for want of the table (it left
                    # the waiting set, so the lines above no longer reach it)
                    self._resend_at = now + REPORT_AFTER
                    self._republish = True
                if now >= deadline:
                    waiting, self._waiting = set(waiting), set()
                    self.unresponsive |= waiting
                    self.given_up += len(waiting)
                    self._due_at = None
                    log.warning("lockstep: %s did not finish t=%.2f within %.1f s: no longer "
                                "waited for", ", ".join(_printable(p) for p in sorted(waiting)),
                                stamp, self.timeout)
                    report = True
                    break
                self._cond.wait(min(deadline - now, 0.05))
        return report

    def _status(self, stamp: float) -> None:
        with self._cond:
            status = LockstepStatus(stamp, tuple(sorted(self.unresponsive)), self.dropped.count,
                                    tuple(sorted(self.rivals)), self.given_up,
                                    self.forgiven + sum(self._their_forgiven.values()))
        self.bus.publish(STATUS, status)

    def close(self) -> None:
        for h in self.handles:
            h.close()

    def __enter__(self) -> "Barrier":
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
