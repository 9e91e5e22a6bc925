"""Lockstep's protocol: its keys, its messages and the limits both sides hold to (the package's
docstring tells how it runs). What the supervisor, the recorder and the access-control
generator need of lockstep is here, and nothing else: importing this loads no participant and
no barrier."""

from __future__ import annotations

import logging

from ..messages import Finite, Message, message

log = logging.getLogger("mrta.lockstep")

STEP = "@mrta/lockstep/step"
DONE = "@mrta/lockstep/done"           # /<participant>
PARTICIPANT = "@mrta/lockstep/participant"  # /<participant>: liveliness
BARRIER = "@mrta/lockstep/barrier"      # /<run>: liveliness of a lockstep simulator
# /<participant>/<robot>: liveliness — the participant answers for that robot too (an agent host
# runs several robots' agents behind one participant: its claims may then be under their names)
SPEAKS = "@mrta/lockstep/speaks"
STATUS = "lockstep/status"

# A participant silent this long (wall s) is given up — but only a live one reaches it: a dead or
# stopped process loses its participant token with its session (at once, or after the 3 s Zenoh
# lease, mrta_zenoh/bus/options.py), and a participant without a token is not waited for. A
# slow one — a busy machine, a CPU-starved process — holds its token and is waited for: giving it
# up would make the run depend on the machine's load, which is what lockstep is there to stop.
DEFAULT_TIMEOUT = 30.0
REPORT_AFTER = 2.5      # wall s: a participant silent this long is reported (still waited for)
ENDED_AFTER = 0.5       # wall s: a participant this late is looked up among the ended (ended.py)
OUTLIVED_AFTER = 4.0    # wall s a token may outlive its process: the 3 s Zenoh lease, and slack
OUTLIVED = "outlived_process"  # the refusal reason of a participant token that did (barrier.py)
STEP_SLACK = 0.05       # simulated s past a participant's `next` a step may stop (one 20 ms step)
STEP_BURST = 1.0        # simulated s a step may jump beyond that without wall time to show for it
NEXT_HORIZON = 10.0     # simulated s: the longest `next` a StepDone may announce
MAX_IN_FLIGHT = 10_000  # samples a claim may be ahead of what arrived and still be waited for
MAX_KEYS = 4096         # keys a Step or StepDone may count
MAX_NAMES = 1024        # participants and runs remembered (a flood of tokens costs bounded memory)
MAX_SPEAKS_FOR = 1024   # robots one participant may answer for (an agent host's team)
FORGIVE_WINDOW = 60.0   # wall s: after a forgiveness, a claimant's unmet claims are not waited for
# A participant still computing (its loop thread's CPU time grows, and it has not answered) says
# so every WORK_BEAT wall seconds (StepDone `working`); the barrier gives up only one silent —
# neither an answer nor a beat — for its timeout, and a working one after WORK_LIMIT timeouts.
WORK_BEAT = 1.0         # wall s between two looks at the loop thread's CPU time
WORK_CPU = 0.005        # CPU s the loop thread must have used since the last look to be working
WORK_LIMIT = 10         # timeouts: the longest a participant that keeps working is waited for
# What one participant may claim in a StepDone (more drops its claims, not the Steps): keys, the
# characters of one key, and of all of them. A patrol agent claims about 11 keys of ≈ 30
# characters; a MURDOCH one a bid key per auctioneer besides — 512 leave room for 500 robots.
CLAIM_KEYS = 512
CLAIM_KEY_CHARS = 256
CLAIM_CHARS = 32 * 1024
LOG_FIRST = 5           # rejected samples logged one by one; then one line per LOG_EVERY


def count_wait(timeout: float) -> float:
    """How long counts that do not arrive are waited for before they are forgiven: half the
    barrier's timeout (so a participant still answers in time), at most 5 s — long enough for
    a CPU-starved process to deliver what it received (forgiving legitimate counts makes a run
    inexact), short enough that a forged claim costs one 5 s pause — once per claimant per
    FORGIVE_WINDOW (Books.at_once; docs/security.md)."""
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
    # not an answer but a request: a step contradicted what this participant took (or it
    # cannot read the table); send the current step again with the whole table (sequence.py)
    resync: bool = False
    # not an answer but a sign of life: this participant is still computing `stamp` (its loop
    # thread used CPU time since its last beat, participant.LoopCpu); `sent` is then empty
    working: bool = False


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


class Rejections:
    """Counted, and logged without flooding: the first few one by one, then one in LOG_EVERY."""

    LOG_EVERY = 1000

    def __init__(self, what: str) -> None:
        self.what = what
        self.count = 0

    def __call__(self, why: str) -> None:
        self.count += 1
        if self.count <= LOG_FIRST or self.count % self.LOG_EVERY == 0:
            log.warning("lockstep: %s rejected (%d so far): %s", self.what, self.count, why)
