"""The fault grammar: which faults a run injects, and when (simulated seconds).

One grammar for every hop the spec makes: an experiment's `failures` list, a mission's `--fail`,
the agent's `$MRTA_CRASH` and `$MRTA_FAULTS`. Each used to parse crash specs its own way (a
regular expression, `float()` with a bound, `float()` without), so an experiment accepted
`robot2@0`, which the demo then refused in every run. The strictest is kept: a robot is an id
as keys carry it (`keys.ID_PATTERN`), a number a plain decimal (no sign, no exponent).

A spec is a comma-separated list of items (docs/delivery.md, "Fault grammar"):

* `ROBOT@T` (or `crash:ROBOT@T`): crash-stop at T — the agent SIGKILLs itself;
* `stall:ROBOT@T`: alive but stuck from T on — it keeps its liveliness token and keeps sending
  what its decision logic says (ALLIANCE's heartbeats, MURDOCH's lease renewals), but its
  layers stop commanding motion, so it makes no progress on its task;
* `partition:ROBOT@T+D`: cut off for D seconds from T — it neither hears nor is heard on the
  coordination keys, then rejoins;
* `loss:P`: each coordination message is lost for each receiver with probability P, drawn from
  the run's seed (the same seed loses the same messages);
* `latency:MEAN±JITTER` (ASCII `MEAN+-JITTER`; `latency:MEAN` alone: no jitter): each
  coordination message is heard MEAN ± JITTER seconds (uniform, seeded) after it was sent.

At most one fault per robot, one `loss`, one `latency`. The channel faults act on the
receiver, per message, from a hash of (seed, receiver, key, sequence number) rather than a
shared random stream: the draw does not depend on the order messages happen to arrive in, so
a lockstep run replays exactly. Departure from a real network: liveliness tokens are never
lost, delayed or cut (a partitioned robot's token stays): the team notices a partition by
silence (ALLIANCE's τ, MURDOCH's lease), which keeps it exact in simulated time.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from typing import NamedTuple

from .keys import ID_PATTERN
from .limits import RUN_DURATION
from .yamlfile import did_you_mean

_NUM = r"\d+(?:\.\d+)?"
_SPEC = re.compile(rf"^({ID_PATTERN})@({_NUM})$")
_PARTITION = re.compile(rf"^({ID_PATTERN})@({_NUM})\+({_NUM})$")
_LATENCY = re.compile(rf"^({_NUM})(?:(?:±|\+-)({_NUM}))?$")
_PROBABILITY = re.compile(rf"^{_NUM}$")
USAGE = "ROBOT@SECONDS, e.g. robot2@30"
KINDS = ("crash", "stall", "partition", "loss", "latency")
GRAMMAR = ("a comma-separated list of ROBOT@T (crash), stall:ROBOT@T, partition:ROBOT@T+D, "
           "loss:P, latency:MEAN±JITTER, e.g. stall:robot2@30,loss:0.1")
ROBOT_KINDS = ("crash", "stall", "partition")


class Failure(NamedTuple):
    """A fault of one robot: `kind` crash, stall or partition (for `duration` seconds)."""

    robot: str
    at: float
    spec: str  # as written: what is passed on, so the next hop reads exactly the same value
    kind: str = "crash"
    duration: float = 0.0


@dataclass(frozen=True)
class Faults:
    """A parsed spec: the robots' faults, in the order written, and the channel's."""

    failures: tuple[Failure, ...] = ()
    loss: float = 0.0
    latency: tuple[float, float] | None = None  # (mean, jitter) seconds
    spec: str = ""

    @property
    def primary(self) -> Failure | None:
        """The robot fault a run's failure report is about: the first one written."""
        return self.failures[0] if self.failures else None

    def __bool__(self) -> bool:
        return bool(self.failures) or self.loss > 0 or self.latency is not None

    def items(self) -> list[str]:
        """The spec's items as written."""
        return [s for s in self.spec.split(",") if s]


def failure_problem(failure: Failure, robots, duration: float) -> str | None:
    """Why `failure` cannot happen in a run of `robots` lasting `duration` simulated seconds
    (a robot the application does not have, a time at or after the end), or None. One check
    for every hop: an experiment's `failures` (at load, naming the line: before, every run
    failed the same way), the mission's `--fail`."""
    robots = list(robots)
    if failure.robot not in robots:
        return (f"{failure.spec}: {failure.robot} is not one of the application's robots "
                f"({', '.join(robots) or 'none'})" + did_you_mean(failure.robot, robots))
    if failure.at >= duration:
        return f"{failure.spec}: {failure.at:g} s is not before the end of the run ({duration:g} s)"
    return None


def faults_problem(faults: Faults, robots, duration: float) -> str | None:
    """`failure_problem` for each robot fault of a spec."""
    robots = list(robots)
    for f in faults.failures:
        problem = failure_problem(f, robots, duration)
        if problem is not None:
            return problem
    return None


def _seconds(text: str, value: str, what: str) -> float:
    problem = RUN_DURATION.problem(float(value))  # 1e308 is > 0 too, but no run lasts that long
    if problem is not None:
        raise ValueError(f"{text!r:.80}: the {what} {problem}")
    return float(value)


def parse_failure(text: str) -> Failure:
    """One robot fault: ROBOT@T (crash), crash:ROBOT@T, stall:ROBOT@T or
    partition:ROBOT@T+D, with T > 0 and D > 0; ValueError (saying what is expected) otherwise."""
    kind, sep, rest = text.partition(":")
    if not sep:
        kind, rest = "crash", text
    if kind not in ROBOT_KINDS:
        raise ValueError(f"{text!r:.80}: expected {USAGE} (seconds > 0), or stall:ROBOT@T, "
                         "partition:ROBOT@T+D" + did_you_mean(kind, KINDS))
    m = (_PARTITION if kind == "partition" else _SPEC).match(rest)
    if m is None or float(m[2]) <= 0 or (kind == "partition" and float(m[3]) <= 0):
        usage = "partition:ROBOT@SECONDS+SECONDS, e.g. partition:robot2@30+10" \
            if kind == "partition" else USAGE if not sep else \
            f"{kind}:ROBOT@SECONDS, e.g. {kind}:robot2@30"
        raise ValueError(f"{text!r:.80}: expected {usage} (seconds > 0)")
    at = _seconds(text, m[2], "time")
    duration = _seconds(text, m[3], "duration") if kind == "partition" else 0.0
    return Failure(m[1], at, text, kind, duration)


def parse_faults(text: str) -> Faults:
    """A whole spec (module docstring); ValueError naming the first bad item."""
    items = [s.strip() for s in text.split(",")]
    if not text.strip() or any(not s for s in items):
        raise ValueError(f"{text!r:.80}: expected {GRAMMAR}")
    failures: list[Failure] = []
    loss, latency = 0.0, None
    seen: set[str] = set()
    for item in items:
        kind, sep, rest = item.partition(":")
        if sep and kind in ("loss", "latency"):
            if kind in seen:
                raise ValueError(f"{text!r:.80}: {kind} given twice")
            seen.add(kind)
            if kind == "loss":
                if not _PROBABILITY.match(rest) or not 0 < float(rest) < 1:
                    raise ValueError(f"{item!r:.80}: expected loss:P with 0 < P < 1, e.g. "
                                     "loss:0.1")
                loss = float(rest)
            else:
                m = _LATENCY.match(rest)
                if m is None:
                    raise ValueError(f"{item!r:.80}: expected latency:MEAN±JITTER (seconds; "
                                     "ASCII +- also), e.g. latency:0.2±0.1")
                mean = _seconds(item, m[1], "mean")
                jitter = _seconds(item, m[2], "jitter") if m[2] and float(m[2]) else 0.0
                if jitter > mean or mean <= 0:
                    raise ValueError(f"{item!r:.80}: the mean must be > 0 and the jitter at most "
                                     "the mean (no message is heard before it is sent)")
                latency = (mean, jitter)
            continue
        failure = parse_failure(item)
        if any(f.robot == failure.robot for f in failures):
            raise ValueError(f"{text!r:.80}: {failure.robot} has two faults (one per robot)")
        failures.append(failure)
    return Faults(tuple(failures), loss, latency, ",".join(items))


def _uniform(*parts: object) -> float:
    """A number in [0, 1) from `parts` alone: the same parts, the same number, in any process.
    hashlib is imported here, not at the top: it loads OpenSSL (≈ 3 MB of every agent's RSS,
    issue #27), and only a run with loss or latency draws."""
    import hashlib

    digest = hashlib.blake2b("\0".join(map(str, parts)).encode(), digest_size=8).digest()
    return int.from_bytes(digest, "big") / 2.0 ** 64


@dataclass(frozen=True)
class FaultPlan:
    """What one robot's agent injects besides a crash: pure, so tests drive it on a manual
    clock. `lost` and `delay` are per received message, keyed by its key and sequence."""

    robot: str
    seed: int = 0
    stall_at: float | None = None
    partitions: tuple[tuple[float, float], ...] = ()  # (from, until) simulated seconds
    loss: float = 0.0
    latency: tuple[float, float] | None = None

    def stalled(self, now: float) -> bool:
        return self.stall_at is not None and now >= self.stall_at

    def cut_off(self, t: float) -> bool:
        return any(a <= t < b for a, b in self.partitions)

    def lost(self, key: str, seq: int) -> bool:
        return self.loss > 0 and _uniform(self.seed, "loss", self.robot, key, seq) < self.loss

    def delay(self, key: str, seq: int) -> float:
        if self.latency is None:
            return 0.0
        mean, jitter = self.latency
        u = _uniform(self.seed, "latency", self.robot, key, seq)
        return mean + jitter * (2.0 * u - 1.0)

    @property
    def channel(self) -> bool:
        """Whether received messages are touched at all."""
        return self.loss > 0 or self.latency is not None or bool(self.partitions)


def plan_for(faults: Faults, robot: str, seed: int) -> FaultPlan | None:
    """This robot's part of `faults` (crashes aside: $MRTA_CRASH), or None if nothing."""
    stall = next((f.at for f in faults.failures if f.robot == robot and f.kind == "stall"), None)
    cuts = tuple((f.at, f.at + f.duration) for f in faults.failures
                 if f.robot == robot and f.kind == "partition")
    if stall is None and not cuts and faults.loss == 0 and faults.latency is None:
        return None
    return FaultPlan(robot, seed, stall, cuts, faults.loss, faults.latency)

