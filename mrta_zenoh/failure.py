"""The fault channel: which faults a run injects, and when (simulated seconds).

One grammar, one parser (`parse_faults`) and one environment variable (`$MRTA_FAULTS`,
FAULTS_ENV) for every fault kind and every hop: an experiment's `failures` list, a mission's
`--fail`, the environment the mission runner gives every process of the run (`fault_env`),
and what each process takes from it (`plan_from_env`: its own part, as a `FaultPlan`). The
agent's `--crash-at S` is shorthand for a crash item naming itself. The strictest reading is
the only one: a robot is an id as keys carry it (`keys.ID_PATTERN`), a number a plain decimal
(no sign, no exponent), so a spec accepted at one hop is never refused at the next.

A spec is a comma-separated list of items (docs/delivery.md, "Fault grammar"):

* `ROBOT@T` (or `crash:ROBOT@T`): crash-stop at T — the process SIGKILLs itself;
* `stall:ROBOT@T`: alive but stuck from T on — it keeps its liveliness token and keeps sending
  what its decision logic says (ALLIANCE's heartbeats, MURDOCH's lease renewals), but its
  layers stop commanding motion, so it makes no progress on its task;
* `partition:ROBOT@T+D`: cut off for D seconds from T — it neither hears nor is heard on the
  coordination keys, then rejoins; what it sends meanwhile is dropped by each receiver (every
  process's plan holds the others' partitions, `FaultPlan.peers_cut`), not by the sender, so
  the recording keeps what it said and the analysis sees it working through the cut;
* `loss:P`: each coordination message is lost for each receiver with probability P, drawn from
  the run's seed (the same seed loses the same messages);
* `latency:MEAN±JITTER` (ASCII `MEAN+-JITTER`; `latency:MEAN` alone: no jitter): each
  coordination message is heard MEAN ± JITTER seconds (uniform, seeded) after it was sent;
* `range:R`: a coordination message between robots farther apart than R metres is dropped
  (CBBA's communication-limited setting), as the receiver's latest ground truth of both robots
  says; a robot whose position it has not heard yet is in range.

Two forms: a *subject* kind strikes one process (`kind:SUBJECT@T`, `+D` for a duration), a
*channel* kind sets one value for the run (`kind:VALUE`). A subject is a robot's id or a *role*,
for specs that must work on any team (an experiment over instances of several sizes):
`@first` — the robot first assigned any task before T, resolved during the run by the agents
themselves (exact in lockstep) — and `@random` — a robot drawn from the instance's own stream,
resolved by the runner before the run (mrta_zenoh/fault_roles.py). At most one fault per subject, one
item of each channel kind. Adding a kind (docs/architecture.md, "Adding a fault kind"): a
`FaultKind` member and its `SYNTAX` row; for a channel kind a field of `Faults` named like the
kind and a value parser in `_VALUES`; then a field of `FaultPlan` and the place that acts on it.

The channel faults act on the receiver, per message, from `seeds.uniform` of (seed, kind,
receiver, key, sequence number) rather than a shared random stream: the draw does not depend on
the order messages happen to arrive in, so a lockstep run replays exactly. Departure from a real
network: liveliness tokens are never lost, delayed or cut (a partitioned robot's token stays):
the team notices a partition by silence (ALLIANCE's τ, MURDOCH's lease), which keeps it exact
in simulated time.
"""

from __future__ import annotations

import dataclasses
import enum
import logging
import math
import os
import re
import signal
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Callable, NamedTuple

from .errors import ConfigError
from .keys import ID_PATTERN
from .limits import RUN_DURATION
from .seeds import uniform
from .timetext import at
from .yamlfile import did_you_mean, plural

FAULTS_ENV = "MRTA_FAULTS"  # the run's fault spec, for every process of the run (fault_env)
# Not read: every fault, crashes included, goes through FAULTS_ENV. Set, it is refused
# (plan_from_env) rather than ignored, so a script written for it does not run faultless.
RETIRED_CRASH_ENV = "MRTA_CRASH"


class FaultKind(str, enum.Enum):
    CRASH = "crash"
    STALL = "stall"
    PARTITION = "partition"
    LOSS = "loss"
    LATENCY = "latency"
    RANGE = "range"

    def __str__(self) -> str:
        return self.value


class Syntax(NamedTuple):
    """How a kind is written: `usage` (in errors), whether it strikes one subject
    (`kind:SUBJECT@T`) and whether it lasts (`+D`)."""

    usage: str
    subject: bool
    lasts: bool = False


SYNTAX: dict[FaultKind, Syntax] = {
    FaultKind.CRASH: Syntax("ROBOT@SECONDS, e.g. robot2@30", True),
    FaultKind.STALL: Syntax("stall:ROBOT@SECONDS, e.g. stall:robot2@30", True),
    FaultKind.PARTITION: Syntax("partition:ROBOT@SECONDS+SECONDS, e.g. partition:robot2@30+10",
                                True, lasts=True),
    FaultKind.LOSS: Syntax("loss:P with 0 < P < 1, e.g. loss:0.1", False),
    FaultKind.LATENCY: Syntax("latency:MEAN±JITTER (seconds; ASCII +- also), e.g. "
                              "latency:0.2±0.1", False),
    FaultKind.RANGE: Syntax("range:R metres > 0, e.g. range:8", False),
}
KINDS = tuple(k.value for k in FaultKind)
USAGE = SYNTAX[FaultKind.CRASH].usage
GRAMMAR = ("a comma-separated list of ROBOT@T (crash), stall:ROBOT@T, partition:ROBOT@T+D, "
           "loss:P, latency:MEAN±JITTER, range:R, e.g. stall:robot2@30,loss:0.1")

_NUM = r"\d+(?:\.\d+)?"
FIRST, RANDOM = "@first", "@random"
ROLES = (FIRST, RANDOM)  # subjects that name a robot by role (module docstring)
_AT = re.compile(rf"^({ID_PATTERN}|{FIRST}|{RANDOM})@({_NUM})(?:\+({_NUM}))?$")
_LATENCY = re.compile(rf"^({_NUM})(?:(?:±|\+-)({_NUM}))?$")
_PROBABILITY = re.compile(rf"^{_NUM}$")


class Failure(NamedTuple):
    """A fault of one subject (a robot): `kind` crash, stall or partition (for `duration`
    seconds) from `at`."""

    robot: str
    at: float
    spec: str  # as written: what is passed on, so the next hop reads exactly the same value
    kind: FaultKind = FaultKind.CRASH
    duration: float = 0.0


@dataclass(frozen=True)
class Faults:
    """A parsed spec: the subjects' faults, in the order written, and the channel's values
    (one field per channel kind, named like it)."""

    failures: tuple[Failure, ...] = ()
    loss: float = 0.0
    latency: tuple[float, float] | None = None  # (mean, jitter) seconds
    range: float | None = None  # metres: messages between robots farther apart are dropped
    spec: str = ""

    @property
    def primary(self) -> Failure | None:
        """The subject fault a run's failure report is about: the first one written."""
        return self.failures[0] if self.failures else None

    def __bool__(self) -> bool:
        return (bool(self.failures) or self.loss > 0 or self.latency is not None
                or self.range is not None)

    def items(self) -> list[str]:
        """The spec's items as written."""
        return [s for s in self.spec.split(",") if s]

    def of(self, subject: str) -> Failure | None:
        """The fault of `subject`, if any (at most one each)."""
        return next((f for f in self.failures if f.robot == subject), None)

    def crashes(self) -> list[Failure]:
        return [f for f in self.failures if f.kind == FaultKind.CRASH]

    def adding(self, failure: Failure) -> Faults:
        """These faults and one more subject fault (`--crash-at`: a crash of the process
        itself); ValueError if its subject already has one."""
        if self.of(failure.robot) is not None:
            raise ValueError(f"{failure.spec}: {failure.robot} already has a fault "
                             f"({self.of(failure.robot).spec}; one per robot)")
        return dataclasses.replace(self, failures=self.failures + (failure,),
                                   spec=",".join([*self.items(), failure.spec]))


def failure_problem(failure: Failure, robots, duration: float) -> str | None:
    """Why `failure` cannot happen in a run of `robots` lasting `duration` simulated seconds
    (a robot the application does not have, a time at or after the end), or None. One check
    for every hop: an experiment's `failures` (at load, naming the line), the mission's
    `--fail`."""
    robots = list(robots)
    if failure.robot not in robots and failure.robot not in ROLES:
        return (f"{failure.spec}: {failure.robot} is not one of the application's robots "
                f"({', '.join(robots) or 'none'})" + did_you_mean(failure.robot, robots))
    if failure.at >= duration:
        return f"{failure.spec}: {failure.at:g} s is not before the end of the run ({duration:g} s)"
    return None


def faults_problem(faults: Faults, robots, duration: float) -> str | None:
    """`failure_problem` for each subject fault of a spec."""
    robots = list(robots)
    for f in faults.failures:
        problem = failure_problem(f, robots, duration)
        if problem is not None:
            return problem
    named = [f.robot for f in faults.failures if f.robot not in ROLES]
    roles = [f for f in faults.failures if f.robot in ROLES]
    if roles and len(robots) - len(named) < len(roles):
        return (f"{roles[0].spec}: a role names a robot no other item names, and "
                f"{plural(len(robots), 'robot')} leave {len(robots) - len(named)} for "
                f"{plural(len(roles), 'role')}")
    return None


def _seconds(text: str, value: str, what: str) -> float:
    problem = RUN_DURATION.problem(float(value))  # 1e308 is > 0 too, but no run lasts that long
    if problem is not None:
        raise ValueError(f"{text!r:.80}: the {what} {problem}")
    return float(value)


def _kind(text: str) -> tuple[FaultKind, str, bool]:
    """An item's kind, the rest of it, and whether the kind was written (`ROBOT@T` is a crash)."""
    name, sep, rest = text.partition(":")
    if not sep:
        return FaultKind.CRASH, text, False
    try:
        return FaultKind(name), rest, True
    except ValueError:
        raise ValueError(f"{text!r:.80}: expected {GRAMMAR}" + did_you_mean(name, KINDS)) \
            from None


def parse_failure(text: str) -> Failure:
    """One subject fault: ROBOT@T (crash), crash:ROBOT@T, stall:ROBOT@T or
    partition:ROBOT@T+D, with T > 0 and D > 0; ValueError (saying what is expected) otherwise."""
    kind, rest, written = _kind(text)
    syntax = SYNTAX[kind]
    if not syntax.subject:
        raise ValueError(f"{text!r:.80}: expected {USAGE} (seconds > 0), or stall:ROBOT@T, "
                         "partition:ROBOT@T+D")
    m = _AT.match(rest)
    if m is None or (m[3] is not None) != syntax.lasts or float(m[2]) <= 0 \
            or (syntax.lasts and float(m[3]) <= 0):
        usage = syntax.usage if written or kind is not FaultKind.CRASH else USAGE
        raise ValueError(f"{text!r:.80}: expected {usage} (seconds > 0; ROBOT a robot's id, "
                         f"{FIRST} or {RANDOM})")
    at = _seconds(text, m[2], "time")
    duration = _seconds(text, m[3], "duration") if syntax.lasts else 0.0
    return Failure(m[1], at, text, kind, duration)


def _loss(item: str, rest: str) -> float:
    if not _PROBABILITY.match(rest) or not 0 < float(rest) < 1:
        raise ValueError(f"{item!r:.80}: expected {SYNTAX[FaultKind.LOSS].usage}")
    return float(rest)


def _latency(item: str, rest: str) -> tuple[float, float]:
    m = _LATENCY.match(rest)
    if m is None:
        raise ValueError(f"{item!r:.80}: expected {SYNTAX[FaultKind.LATENCY].usage}")
    mean = _seconds(item, m[1], "mean")
    jitter = _seconds(item, m[2], "jitter") if m[2] and float(m[2]) else 0.0
    if jitter > mean or mean <= 0:
        raise ValueError(f"{item!r:.80}: the mean must be > 0 and the jitter at most the mean "
                         "(no message is heard before it is sent)")
    return mean, jitter


def _range(item: str, rest: str) -> float:
    if not _PROBABILITY.match(rest) or not float(rest) > 0:
        raise ValueError(f"{item!r:.80}: expected {SYNTAX[FaultKind.RANGE].usage}")
    return float(rest)


# channel kind → its value's parser; the value goes to the `Faults` field of the kind's name
_VALUES: dict[FaultKind, Callable[[str, str], object]] = {FaultKind.LOSS: _loss,
                                                         FaultKind.LATENCY: _latency,
                                                         FaultKind.RANGE: _range}


def parse_faults(text: str) -> Faults:
    """A whole spec (module docstring); ValueError naming the first bad item."""
    items = [s.strip() for s in text.split(",")]
    if not text.strip() or any(not s for s in items):
        raise ValueError(f"{text!r:.80}: expected {GRAMMAR}")
    failures: list[Failure] = []
    values: dict[str, object] = {}
    for item in items:
        kind, rest, _ = _kind(item)
        if not SYNTAX[kind].subject:
            if kind.value in values:
                raise ValueError(f"{text!r:.80}: {kind} given twice")
            values[kind.value] = _VALUES[kind](item, rest)
            continue
        failure = parse_failure(item)
        if any(f.robot == failure.robot for f in failures):
            raise ValueError(f"{text!r:.80}: {failure.robot} has two faults (one per robot)")
        failures.append(failure)
    return Faults(tuple(failures), spec=",".join(items), **values)


def fault_env(faults: Faults) -> dict[str, str]:
    """The environment that hands `faults` to every process of a run: the whole spec, in one
    variable, whatever the kinds — each process takes its own part (`plan_from_env`)."""
    return {FAULTS_ENV: faults.spec} if faults else {}


def faults_from_env(environ: Mapping[str, str] | None = None) -> Faults:
    """$MRTA_FAULTS parsed (empty if unset); a bad one is a ConfigError, before any bus opens."""
    environ = os.environ if environ is None else environ
    if environ.get(RETIRED_CRASH_ENV):
        raise ConfigError(f"${RETIRED_CRASH_ENV} is not read: every fault, crashes included, "
                          f"goes through ${FAULTS_ENV} (e.g. {FAULTS_ENV}="
                          f"{environ[RETIRED_CRASH_ENV]})")
    text = environ.get(FAULTS_ENV, "")
    if not text:
        return Faults()
    try:
        return parse_faults(text)
    except ValueError as exc:
        raise ConfigError(f"${FAULTS_ENV}: {exc}") from None


@dataclass(frozen=True)
class FaultPlan:
    """What one process injects into itself: pure, so tests drive it on a manual clock.
    `lost` and `delay` are per received message, keyed by its key and sequence number."""

    robot: str
    seed: int = 0
    stall_at: float | None = None
    partitions: tuple[tuple[float, float], ...] = ()  # (from, until) simulated seconds
    loss: float = 0.0
    latency: tuple[float, float] | None = None
    crash_at: float | None = None
    range: float | None = None
    # an `@first` fault not resolved yet: the agent resolves it at its time, from who was
    # assigned first among the robots no item names (`taken`), and then strikes or drops it
    first: Failure | None = None
    taken: frozenset[str] = frozenset()
    # the other subjects' partitions (subject, from, until): a partitioned robot still
    # transmits — its messages are in the recording, which is what it did and said — and every
    # receiver drops what it sent in its window (`sender_cut`), as a network would
    peers_cut: tuple[tuple[str, float, float], ...] = ()

    def struck(self, failure: Failure) -> FaultPlan:
        """This plan with `failure` (a role's, once resolved to this subject) its own."""
        kind = FaultKind(failure.kind)
        return dataclasses.replace(
            self, first=None,
            crash_at=failure.at if kind is FaultKind.CRASH else self.crash_at,
            stall_at=failure.at if kind is FaultKind.STALL else self.stall_at,
            partitions=self.partitions + (((failure.at, failure.at + failure.duration),)
                                          if kind is FaultKind.PARTITION else ()))

    def crashed(self, now: float) -> bool:
        return self.crash_at is not None and now >= self.crash_at

    def stalled(self, now: float) -> bool:
        return self.stall_at is not None and now >= self.stall_at

    def cut_off(self, t: float) -> bool:
        return any(a <= t < b for a, b in self.partitions)

    def sender_cut(self, sender: str, stamp: float) -> bool:
        """Whether `sender` was cut off by its partition when it sent at `stamp`."""
        return any(who == sender and a <= stamp < b for who, a, b in self.peers_cut)

    def resolved(self, who: str | None) -> FaultPlan:
        """This plan once its `@first` item struck `who` (None: nobody): this subject's own
        fault if it is `who`, else — for a partition — a peer's cut to honour."""
        first = self.first
        if first is None:
            return self
        if who == self.robot:
            return self.struck(first)
        cut = ((who, first.at, first.at + first.duration),) \
            if who is not None and FaultKind(first.kind) is FaultKind.PARTITION else ()
        return dataclasses.replace(self, first=None, peers_cut=self.peers_cut + cut)

    def lost(self, key: str, seq: int) -> bool:
        return self.loss > 0 and uniform(self.seed, "loss", self.robot, key, seq) < self.loss

    def delay(self, key: str, seq: int) -> float:
        if self.latency is None:
            return 0.0
        mean, jitter = self.latency
        u = uniform(self.seed, "latency", self.robot, key, seq)
        return mean + jitter * (2.0 * u - 1.0)

    def out_of_range(self, here: tuple[float, float] | None,
                     there: tuple[float, float] | None) -> bool:
        """Whether a message between robots at `here` and `there` is dropped (`range:R`); an
        unknown position is in range."""
        return (self.range is not None and here is not None and there is not None
                and math.dist(here, there) > self.range)

    @property
    def channel(self) -> bool:
        """Whether received messages are touched at all."""
        return (self.loss > 0 or self.latency is not None or bool(self.partitions)
                or self.range is not None)


def plan_for(faults: Faults, subject: str, seed: int) -> FaultPlan | None:
    """`subject`'s part of `faults` (its own fault, the channel's, and an `@first` it may turn
    out to be — not if an item names it), or None if nothing. `@random` is the runner's to
    resolve before the run: one left here is refused (ValueError)."""
    if faults.of(RANDOM) is not None:
        raise ValueError(f"{faults.of(RANDOM).spec}: {RANDOM} is drawn by the runner before "
                         "the run (mrta demo, mrta experiment): give the robot's id")
    own = faults.of(subject)
    first = faults.of(FIRST)
    # a subject named by an item is never `@first` (taken), but it must learn whom an
    # `@first` partition cut off, to drop what that robot sends
    if own is not None and first is not None and FaultKind(first.kind) is not FaultKind.PARTITION:
        first = None
    peers_cut = tuple((f.robot, f.at, f.at + f.duration) for f in faults.failures
                      if FaultKind(f.kind) is FaultKind.PARTITION and f.robot != subject
                      and f.robot not in ROLES)
    if own is None and first is None and not peers_cut and faults.loss == 0 \
            and faults.latency is None and faults.range is None:
        return None
    taken = frozenset(f.robot for f in faults.failures if f.robot not in ROLES) \
        if first is not None else frozenset()
    plan = FaultPlan(subject, seed, loss=faults.loss, latency=faults.latency, first=first,
                     taken=taken, range=faults.range, peers_cut=peers_cut)
    # struck() settles the plan's own `@first`; a named subject keeps the item (a partition's)
    return dataclasses.replace(plan.struck(own), first=first) if own is not None else plan


def plan_from_env(subject: str, seed: int, crash_at: float | None = None,
                  environ: Mapping[str, str] | None = None) -> FaultPlan | None:
    """What process `subject` injects into itself in run `seed`: its part of $MRTA_FAULTS, and
    `crash_at` (`--crash-at`, shorthand for a crash item naming it). ConfigError on a bad spec
    or a second fault for it, before any bus opens."""
    faults = faults_from_env(environ)
    if crash_at is not None:
        try:
            faults = faults.adding(Failure(subject, crash_at, f"crash:{subject}@{crash_at:g}"))
        except ValueError as exc:
            raise ConfigError(f"--crash-at and ${FAULTS_ENV}: {exc}") from None
    try:
        return plan_for(faults, subject, seed)
    except ValueError as exc:
        raise ConfigError(f"${FAULTS_ENV}: {exc}") from None


def say_crash(subject: str, now: float, log: logging.Logger) -> None:
    """The line a crash is told by, a process's or a hosted robot's alike (the mission runner
    reads it for a hosted robot: supervisor/mission/hosting.py)."""
    log.warning("%s: crashing %s as asked (fault injection)", subject, at(now))


def crash_now(subject: str, now: float, log: logging.Logger) -> None:
    """The crash itself: SIGKILL, no shutdown, no goodbye — its token goes with its session."""
    say_crash(subject, now, log)
    logging.shutdown()
    os.kill(os.getpid(), signal.SIGKILL)
