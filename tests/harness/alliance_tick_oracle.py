"""The reference for tests/test_tick_scaling.py: HighLevel.tick as it was before it became
incremental — every tick rescans every record heard. Kept verbatim (only the import changed) so
the incremental version can be checked against it step by step; the header below is the
original's.

ALLIANCE's high level (Parker 1998; dissertation appendix E), as pure logic on virtual time.

`HighLevel.tick(now)` runs one motivation update of every behaviour set and returns what to
publish. Nothing here touches the bus or reads the system clock: the agent feeds it sensory
feedback and other robots' broadcasts with their reception times, and tests drive it by hand.

Per behaviour set j (task h), every tick, with ρ = spin_rate, τ = timeout_duration:
    motivation = (motivation + impatience) · applicable · ¬suppressed · ¬reset · ¬acquiescent
    active  ⇔  motivation ≥ θ   (saturated at θ while active; at most one active set)

Deliberate choices, where appendix E or the original C++ (reference/) leave room or go wrong:
  * Rates are per tick, as in E.8/E.10 (time to activate ≈ (θ − m)/(impatience · ρ)).
  * Motivation is exact: θ, fast_rate, ρ and announced expected_durations are taken as the
    decimals they were written as (`exact`: 0.1 is 1/10, not 0.1000000000000000055…) and
    motivation and impatience are sums of rationals, so a set activates exactly on tick
    ⌈θ/δ_fast⌉ as a hand computation says (θ=1, δ_fast=0.1: tick 10; ten float additions of
    0.1 make 0.9999999999999999 and tick 11). Published Motivation samples carry floats.
  * Slow rate (E.7's δ_slow): chosen so that motivation reaches θ in the announcing robot's
    `expected_duration` at *this* robot's tick rate: θ / (expected_duration · ρ). The C++ used
    θ / expected_duration regardless of ρ. If that would exceed fast_rate, fast_rate is used and
    a warning is logged once — the C++ killed the node.
  * φ (E.7, the time this robot allows another to do the task): the other robot's announced
    expected_duration. Once it has been broadcasting for longer, impatience returns to fast.
    A broadcast whose expected_duration is not in (0, max_expected_duration] is refused
    (the agent counts it): a forged 1e300 must not freeze everybody's impatience.
  * Suppression (E.2, dissertation line 2549): a true OR over the other sets' activity *at
    the start of the tick*, so
    the result does not depend on the order of `behaviour_set0/1/…` (a set that gives up in a
    tick does not un-suppress the sets listed after it in the same tick). If several sets cross
    θ on the same tick, the one furthest past its threshold (θ-normalised) wins; the C++ used
    "last toggle wins".
  * Acquiescence (E.5/E.6, lines 2566–2576): "more than" — yielding when active for *more
    than* ψ, giving up when active for more than λ. A robot that yields gives the robot it
    yielded to a whole φ again (its impatience is slow for that robot's expected_duration
    from the yield), as E.4's reset gives a newcomer: it does not take the task straight back.
  * Who yields (E.5 and E.4 together): broadcasts carry `active_since`, the time on the
    sender's clock at which its current activation began (an addition to alliance_msgs; a
    client that does not send it is handled as described below). Two robots doing the same
    single-robot task are ordered by (active_since, robot id); the *earlier* one is the one that
    acquiesces once it has been active for more than ψ — Parker's rule that a robot which has
    done a task for ψ gives way to one that has taken it over. Both robots compare the same two
    reported numbers, so they always agree on who yields, whatever the clocks' offset; identical
    robots that activate on the same tick differ by id. This replaces E.6's "yield when another
    robot does the task" (line 2573), under which two robots that hear each other both yield
    (after a partition heals nobody did the task for 3 s, and robots ticking in phase
    livelocked). Bound: once two holders hear each other, the earlier yields within ψ + one
    tick (ψ + τ + one tick counting a lost broadcast) — identical robots started in phase
    included; the later one does not yield to it meanwhile, so there is no gap.
  * One-way links (the later holder hears the earlier one, which never hears it — a dead
    subscriber, an asymmetric radio link). Parker's E.6 covers this case, as every listener
    yields (after ψ) to any robot it hears on its task; the ordering above alone would leave
    both holding until λ (a reference replay: duplicated 89 % of the time). So a later holder
    also yields to an *earlier* holder that cannot be hearing it: one it has heard on every
    tick while active for more than ψ + 2τ + two of that robot's broadcast intervals (ψ and τ
    its own), whose φ (announced expected_duration) has run out since it was first heard, and
    which is still broadcasting (heard within 1.5 of its intervals). Had the earlier one heard
    us, it would have yielded by its activation + its ψ, or a tick after first hearing us,
    and its broadcasts would have lapsed here a delivery delay + τ after its last one. Then the
    later one gives the earlier a whole φ (above) before its impatience is fast again:
    under a permanent one-way link duplication falls to about
    (ψ + 2τ + 2/broadcast_rate) / (that + φ + ⌈θ/δ_fast⌉/ρ) of the time (measured on the
    team harness: 32–38 % where the rule-less version held 49–78 %).
    Limits — the no-gap guarantee for two-way links rests on delivery delays under τ
    and, for each pair, either the earlier robot's ψ not longer than the later's, or its ψ +
    τ + a tick + the largest delay shorter than the expected_duration it announces (then its
    φ running out proves it would have yielded). Outside these, both may stop at once and
    the task is uncovered for at most the takeover bound. The reverse one-way link (only the earlier holder hears) needs no new
    rule: it yields after ψ as above. Detecting a one-way link exactly would need broadcasts
    to say whom their sender hears (a wire change).
  * Reset (E.4, line 2559) applies to a set that is *not active*: its motivation returns to 0 when
    another robot newly starts the task — newly meaning a new `active_since`, not a new run of
    receptions: an activation is identified by (robot, active_since). Late, lost or jittered
    broadcasts therefore never reset anybody, a robot heard again after a partition or any
    silence, however long, is not "new", and an active robot is never reset (the ordering
    above decides between active robots). The last activation heard from each robot is kept
    for as long as this robot runs (one record per robot and task; the agent only passes on
    broadcasts from its team, whose size it bounds). The C++ latched the reset once per
    process; an earlier version of ours forgot a robot silent for 10τ, so the same activation
    heard again reset everybody's impatience a second time.
    For a sender without `active_since`, a new start is a lapse of freshness longer than
    max(τ, 1.5 × its observed broadcast interval (τ until one is observed)), and its start is
    taken as when this robot first heard the run.
  * A robot that was frozen (SIGSTOP, a stalled process) keeps its old `active_since`, so the
    robot that took over while it was away is the later one and keeps the task: a resumed robot
    does not evict its replacement — *with synchronised clocks* (simulated time, NTP/PTP). The
    two `active_since` are read on two clocks: if the replacement's clock runs behind the
    resumed robot's by more than the time between their activations, the replacement looks
    earlier and is the one that yields. Both still agree on who yields (they compare the same
    two numbers), so there is neither a gap nor a lasting duplicate, only the wrong robot kept.
  * The takeover bound (architecture.py) counts from the dead robot's last broadcast as
    *received* (`on_broadcast`'s `now`): its freshness lasts τ from there. Measured from its
    death, add the largest delivery delay (in lockstep a broadcast counts as heard at its own
    stamp, so none).
  * τ must be longer than a tick (the parameter loader rejects τ ≤ 1/ρ: a teammate heard
    between two ticks would never be seen) and should be at least twice the effective broadcast
    period (broadcasts leave on ticks: the loader warns).
"""

from __future__ import annotations

import functools
import logging
import math
from dataclasses import dataclass, field
from fractions import Fraction

from robot_agent.alliance.params import BehaviourSetParams, RobotParams

log = logging.getLogger("mrta.alliance")

UNKNOWN = -1.0  # active_since of a sender that does not report it
ZERO = Fraction(0)


def exact(x: float) -> Fraction:
    """A parameter as the decimal it was written as (YAML gives floats; their shortest repr is
    what the user typed): 0.1 → 1/10. Finite input only."""
    return Fraction(repr(float(x)))


@functools.lru_cache(maxsize=256)
def slow_rate(theta: Fraction, expected_duration: float, rho: Fraction) -> Fraction:
    """δ_slow per tick: θ over the other robot's expected duration at our tick rate (cached:
    a teammate announces the same duration on every broadcast)."""
    return theta / (exact(expected_duration) * rho)


@dataclass
class OtherRobot:
    """What this robot knows of another robot doing one task (E.3's communication record)."""

    first_heard: float    # when this robot first heard the current activation
    last_heard: float
    expected_duration: float
    active_since: float   # on the sender's clock; UNKNOWN if it does not say
    interval: float = 0.0  # last interval between two of its broadcasts (for UNKNOWN senders)
    new: bool = True      # a new activation not yet seen by a tick
    phi_from: float = math.nan  # φ (E.7) runs from here: first heard, or when we yielded to it
    overlap_since: float | None = None  # first tick both active, it earlier, heard every tick

    def __post_init__(self) -> None:
        if math.isnan(self.phi_from):
            self.phi_from = self.first_heard

    def started(self) -> float:
        """The start that orders this robot against others (its own report if it has one)."""
        return self.active_since if self.active_since != UNKNOWN else self.first_heard


@dataclass
class SetState:
    params: BehaviourSetParams
    theta: Fraction = ZERO     # exact(params.threshold)
    fast: Fraction = ZERO      # exact(params.fast_rate)
    exact_motivation: Fraction = ZERO
    exact_impatience: Fraction = ZERO
    applicable: bool = False
    suppressed: bool = False
    resetted: bool = False
    acquiescent: bool = False
    active: bool = False
    activated_at: float | None = None
    feedback: bool = False
    feedback_stamp: float | None = None
    others: dict[str, OtherRobot] = field(default_factory=dict)
    warned_slow: bool = False

    def __post_init__(self) -> None:
        self.theta, self.fast = exact(self.params.threshold), exact(self.params.fast_rate)

    @property
    def motivation(self) -> float:
        return float(self.exact_motivation)

    @property
    def impatience(self) -> float:
        return float(self.exact_impatience)


@dataclass(frozen=True)
class MotivationState:
    """One set's state after a tick; the agent turns it into an alliance_msgs/Motivation."""

    task_id: str
    impatience: float
    acquiescent: bool
    suppressed: bool
    resetted: bool
    applicable: bool
    motivation: float
    threshold: float
    active: bool


@dataclass(frozen=True)
class TaskSwitch:
    """A change worth telling the user: an activation, a deactivation, or the reset of a set
    that was not active (`active` is then False and the set was already inactive)."""

    task_id: str
    active: bool
    reason: str  # threshold reached | yielded to … | gave up … | … started the task | inapplicable | suppressed
    kind: str = ""  # activated | deactivated | reset

    def __post_init__(self) -> None:
        if not self.kind:
            object.__setattr__(self, "kind", "activated" if self.active else "deactivated")


class HighLevel:
    def __init__(self, robot_id: str, params: RobotParams, feedback_timeout: float | None = None):
        self.robot_id = robot_id
        self.params = params
        self.rho = params.spin_rate
        self.exact_rho = exact(params.spin_rate)
        self.tau = params.timeout_duration
        self.tick_period = 1.0 / params.spin_rate
        self.max_expected = params.max_expected_duration
        # Sensory feedback is held for this long; after that the set is inapplicable.
        self.feedback_timeout = feedback_timeout if feedback_timeout is not None else max(
            3.0 / params.spin_rate, 1.0)
        self.sets = {bs.task_id: SetState(bs) for bs in params.behaviour_sets}

    # ------------------------------------------------------------ inputs
    def on_feedback(self, task_id: str, applicable: bool, now: float) -> None:
        s = self.sets.get(task_id)
        if s is not None:
            s.feedback, s.feedback_stamp = applicable, now

    def sane_expected(self, expected_duration: float) -> bool:
        return math.isfinite(expected_duration) and 0.0 < expected_duration <= self.max_expected

    def on_broadcast(self, robot_id: str, task_id: str, expected_duration: float, now: float,
                     active_since: float = UNKNOWN) -> bool:
        """Another robot announced it is doing `task_id` (received at `now`, our clock).

        False when the broadcast is refused (our own, an unknown task, an absurd
        expected_duration); the caller counts those."""
        if robot_id == self.robot_id or not self.sane_expected(expected_duration):
            return False
        if not math.isfinite(active_since):
            active_since = UNKNOWN
        s = self.sets.get(task_id)
        if s is None:
            return False
        rec = s.others.get(robot_id)
        if rec is None or self._new_activation(rec, active_since, now):
            s.others[robot_id] = OtherRobot(now, now, expected_duration, active_since)
        else:
            rec.interval = now - rec.last_heard
            rec.last_heard, rec.expected_duration = now, expected_duration
        return True

    def _new_activation(self, rec: OtherRobot, active_since: float, now: float) -> bool:
        if active_since != UNKNOWN or rec.active_since != UNKNOWN:
            return active_since != rec.active_since
        # a sender without active_since: a lapse longer than its broadcasts' own jitter (its
        # interval unknown after one broadcast: assume the worst legal one, τ)
        return now - rec.last_heard > max(self.tau, 1.5 * (rec.interval or self.tau))

    @property
    def active_task(self) -> str | None:
        for task, s in self.sets.items():
            if s.active:
                return task
        return None

    def active_since(self) -> float:
        """When the current activation began (what broadcasts report), UNKNOWN if idle."""
        task = self.active_task
        return self.sets[task].activated_at if task is not None else UNKNOWN

    # ------------------------------------------------------------ the update
    def tick(self, now: float) -> tuple[list[MotivationState], list[TaskSwitch]]:
        transitions: list[TaskSwitch] = []
        candidates: list[tuple[float, str]] = []
        was_active = {task for task, s in self.sets.items() if s.active}  # E.2: previous tick
        for task, s in self.sets.items():
            p = s.params
            s.applicable = s.feedback and s.feedback_stamp is not None and \
                now - s.feedback_stamp <= self.feedback_timeout
            s.suppressed = any(t != task for t in was_active)
            fresh = {k: r for k, r in s.others.items() if now - r.last_heard <= self.tau}
            started = [k for k, r in fresh.items() if r.new]
            for r in s.others.values():
                r.new = False
            # E.4, for a set that is not active: another robot newly started the task
            s.resetted = bool(started) and not s.active
            if s.resetted and s.exact_motivation > 0:
                transitions.append(TaskSwitch(task, False, f"{', '.join(sorted(started))} "
                                                           "started the task", "reset"))
            active_for = now - s.activated_at if s.active and s.activated_at is not None else -1.0
            later = self._later_holders(s, fresh) if s.active else []
            unheeded = self._unheeding_earlier(s, fresh, now)
            yielded = bool(later) and active_for > p.yielding_delay
            gave_up = active_for > p.giving_up_delay
            s.acquiescent = s.active and (yielded or bool(unheeded) or gave_up)
            if s.active and (yielded or unheeded):
                for k in later if yielded else unheeded:  # a whole φ again for it
                    s.others[k].phi_from = now
            s.exact_impatience = self._impatience(s, fresh, now)
            keep = s.applicable and not s.suppressed and not s.resetted and not s.acquiescent
            if keep:
                s.exact_motivation = s.exact_motivation + s.exact_impatience
            else:
                if s.active:
                    if yielded:
                        reason = f"yielded to {later[0]} (it took the task over later)"
                    elif unheeded:
                        reason = (f"yielded to {unheeded[0]} (active before it and still "
                                  f"broadcasting after ψ + 2τ: it does not hear this robot)")
                    elif s.acquiescent:
                        reason = f"gave up after {active_for:.1f} s (giving_up_delay {p.giving_up_delay:g} s)"
                    elif not s.applicable:
                        reason = "inapplicable"
                    else:
                        reason = "suppressed"
                    transitions.append(TaskSwitch(task, False, reason))
                s.exact_motivation = ZERO
                s.active = False
                s.activated_at = None
            if s.active:
                s.exact_motivation = min(s.exact_motivation, s.theta)
            elif s.exact_motivation >= s.theta:
                candidates.append((s.exact_motivation / s.theta, task))
        # A set beside one that was active when the tick began is suppressed (motivation 0),
        # so candidates only exist when none was; only one activates.
        if candidates:
            candidates.sort(key=lambda c: -c[0])  # stable: ties go to the first listed set
            _, winner = candidates[0]
            for _, task in candidates[1:]:
                s = self.sets[task]
                s.suppressed, s.exact_motivation = True, ZERO
            s = self.sets[winner]
            s.active, s.activated_at = True, now
            s.exact_motivation = s.theta
            transitions.append(TaskSwitch(winner, True, "threshold reached"))
        states = [MotivationState(t, s.impatience, s.acquiescent, s.suppressed, s.resetted,
                                  s.applicable, s.motivation, float(s.theta), s.active)
                  for t, s in self.sets.items()]
        return states, transitions

    def _later_holders(self, s: SetState, fresh: dict[str, OtherRobot]) -> list[str]:
        """Robots doing this task whose activation comes after ours in (start, id) order."""
        mine = (s.activated_at, self.robot_id)
        return sorted(k for k, r in fresh.items() if (r.started(), k) > mine)

    def _unheeding_earlier(self, s: SetState, fresh: dict[str, OtherRobot],
                           now: float) -> list[str]:
        """Holders of this task whose activation comes before ours and that cannot be hearing
        us (header: one-way links): heard on every tick while we were active for more than
        ψ + 2τ + two of its broadcast intervals, past its φ since we first heard it, and
        still broadcasting now."""
        limit = s.params.yielding_delay + 2 * self.tau
        mine = (s.activated_at, self.robot_id)
        out = []
        for k, r in s.others.items():
            if s.active and k in fresh and (r.started(), k) < mine:
                if r.overlap_since is None:
                    r.overlap_since = now
                elif (now - r.overlap_since > limit + 2 * r.interval
                      and now - r.first_heard > r.expected_duration and self._recent(r, now)):
                    out.append(k)
            else:
                r.overlap_since = None
        return sorted(out)

    def _recent(self, r: OtherRobot, now: float) -> bool:
        """Heard within 1.5 of its own broadcast intervals (τ before one is observed): still
        broadcasting now, not merely fresh — a holder that stopped (yielding to us) shows
        within about one broadcast period instead of τ."""
        return now - r.last_heard <= 1.5 * (r.interval or self.tau)

    def _impatience(self, s: SetState, fresh: dict[str, OtherRobot], now: float) -> Fraction:
        p = s.params
        slow_rates = []
        for r in fresh.values():
            if now - r.phi_from < r.expected_duration:  # within φ: let it work
                slow_rates.append(slow_rate(s.theta, r.expected_duration, self.exact_rho))
        if not slow_rates:
            return s.fast
        slow = min(slow_rates)
        if slow > s.fast:
            if not s.warned_slow:
                log.warning(
                    "%s/%s: slow impatience %.3g per tick (θ=%g over another robot's expected "
                    "duration at %g Hz) exceeds fast_rate %g; using fast_rate",
                    self.robot_id, p.task_id, float(slow), p.threshold, self.rho, p.fast_rate)
                s.warned_slow = True
            return s.fast
        return slow
