"""ALLIANCE's high level (Parker 1998; dissertation appendix E), as pure logic on virtual time.

`HighLevel.tick(now)` runs one motivation update of every behaviour set and returns what to
publish. Nothing here touches the bus or reads the system clock: the agent feeds it sensory
feedback and other robots' broadcasts with their reception times, and tests drive it by hand.

Per behaviour set j (task h), every tick, with ρ = spin_rate, τ = timeout_duration:
    motivation = (motivation + impatience) · applicable · ¬suppressed · ¬reset · ¬acquiescent
    active  ⇔  motivation ≥ θ   (saturated at θ while active; at most one active set)

Deliberate choices, where appendix E or the original C++ (reference/) leave room or go wrong:
  * Rates are per tick, as in E.8/E.10 (time to activate ≈ (θ − m)/(impatience · ρ)).
  * Slow rate (E.7's δ_slow): chosen so that motivation reaches θ in the announcing robot's
    `expected_duration` at *this* robot's tick rate: θ / (expected_duration · ρ). The C++ used
    θ / expected_duration regardless of ρ. If that would exceed fast_rate, fast_rate is used and
    a warning is logged once — the C++ killed the node.
  * φ (E.7, the time this robot allows another to do the task): the other robot's announced
    expected_duration. Once it has been broadcasting for longer, impatience returns to fast.
  * Reset (E.4): fires on each rising edge of "robot k's broadcasts for this task are fresh",
    i.e. once for each robot that newly starts the task (and again if it lapsed for > τ and
    starts anew — a new attempt deserves a fresh allowance). The C++ latched it once per process.
  * Suppression (E.2): a true OR over the other sets' previous activation; if several sets
    cross θ on the same tick, the one furthest past its threshold (θ-normalised) wins and the
    others count as suppressed. The C++ used "last toggle wins".
  * τ must be > 0 (the parameter loader rejects τ ≤ 0; the C++ hung).
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, field

from .params import BehaviourSetParams, RobotParams

log = logging.getLogger("mrta.alliance")


@dataclass
class OtherRobot:
    """What this robot knows of another robot doing one task (E.3's communication record)."""

    first_heard: float  # start of the current run of fresh broadcasts
    last_heard: float
    expected_duration: float
    fresh_at_last_tick: bool = False


@dataclass
class SetState:
    params: BehaviourSetParams
    motivation: float = 0.0
    impatience: float = 0.0
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
    task_id: str
    active: bool
    reason: str  # threshold reached | acquiesced (yielded) | gave up | reset | inapplicable | suppressed


class HighLevel:
    def __init__(self, robot_id: str, params: RobotParams, feedback_timeout: float | None = None):
        self.robot_id = robot_id
        self.params = params
        self.rho = params.spin_rate
        self.tau = params.timeout_duration
        # Sensory feedback is held for this long; after that the set is inapplicable.
        self.feedback_timeout = feedback_timeout if feedback_timeout is not None else max(
            3.0 / params.spin_rate, 1.0)
        self.sets = {bs.task_id: SetState(bs) for bs in params.behaviour_sets}

    # ------------------------------------------------------------ inputs
    def on_feedback(self, task_id: str, applicable: bool, now: float) -> None:
        s = self.sets.get(task_id)
        if s is not None:
            s.feedback, s.feedback_stamp = applicable, now

    def on_broadcast(self, robot_id: str, task_id: str, expected_duration: float, now: float) -> None:
        """Another robot announced it is doing `task_id` (received at `now`, our clock)."""
        if robot_id == self.robot_id:
            return
        s = self.sets.get(task_id)
        if s is None:
            return
        rec = s.others.get(robot_id)
        if rec is None or now - rec.last_heard > self.tau:
            s.others[robot_id] = OtherRobot(now, now, expected_duration)
        else:
            rec.last_heard, rec.expected_duration = now, expected_duration

    @property
    def active_task(self) -> str | None:
        for task, s in self.sets.items():
            if s.active:
                return task
        return None

    # ------------------------------------------------------------ the update
    def tick(self, now: float) -> tuple[list[MotivationState], list[TaskSwitch]]:
        transitions: list[TaskSwitch] = []
        candidates: list[tuple[float, str]] = []
        for task, s in self.sets.items():
            p = s.params
            s.applicable = s.feedback and s.feedback_stamp is not None and \
                now - s.feedback_stamp <= self.feedback_timeout
            s.suppressed = any(o.active for t, o in self.sets.items() if t != task)
            fresh = {k: r for k, r in s.others.items() if now - r.last_heard <= self.tau}
            s.resetted = False
            for k, r in s.others.items():
                is_fresh = k in fresh
                if is_fresh and not r.fresh_at_last_tick:
                    s.resetted = True
                r.fresh_at_last_tick = is_fresh
            active_for = now - s.activated_at if s.active and s.activated_at is not None else -1.0
            yielded = bool(fresh) and active_for >= p.yielding_delay
            gave_up = active_for >= p.giving_up_delay
            s.acquiescent = s.active and (yielded or gave_up)
            s.impatience = self._impatience(s, fresh, now)
            keep = s.applicable and not s.suppressed and not s.resetted and not s.acquiescent
            if keep:
                s.motivation = s.motivation + s.impatience
            else:
                if s.active:
                    reason = ("acquiesced (yielded)" if yielded else "gave up") if s.acquiescent else \
                        "reset" if s.resetted else "inapplicable" if not s.applicable else "suppressed"
                    transitions.append(TaskSwitch(task, False, reason))
                s.motivation = 0.0
                s.active = False
                s.activated_at = None
            if s.active:
                s.motivation = min(s.motivation, p.threshold)
            elif s.motivation >= p.threshold:
                candidates.append((s.motivation / p.threshold, task))
        # A set beside an active one is suppressed (motivation 0), so candidates only exist
        # while no set is active.
        if candidates:
            candidates.sort(key=lambda c: -c[0])  # stable: ties go to the first listed set
            _, winner = candidates[0]
            for _, task in candidates[1:]:
                s = self.sets[task]
                s.suppressed, s.motivation = True, 0.0
            s = self.sets[winner]
            s.active, s.activated_at = True, now
            s.motivation = s.params.threshold
            transitions.append(TaskSwitch(winner, True, "threshold reached"))
        states = [MotivationState(t, s.impatience, s.acquiescent, s.suppressed, s.resetted,
                                  s.applicable, s.motivation, s.params.threshold, s.active)
                  for t, s in self.sets.items()]
        return states, transitions

    def _impatience(self, s: SetState, fresh: dict[str, OtherRobot], now: float) -> float:
        p = s.params
        slow_rates = []
        for r in fresh.values():
            if now - r.first_heard < r.expected_duration:  # within φ: let it work
                slow_rates.append(p.threshold / (r.expected_duration * self.rho))
        if not slow_rates:
            return p.fast_rate
        slow = min(slow_rates)
        if slow > p.fast_rate:
            if not s.warned_slow:
                log.warning(
                    "%s/%s: slow impatience %.3g per tick (θ=%g over another robot's expected "
                    "duration at %g Hz) exceeds fast_rate %g; using fast_rate",
                    self.robot_id, p.task_id, slow, p.threshold, self.rho, p.fast_rate)
                s.warned_slow = True
            return p.fast_rate
        return slow
