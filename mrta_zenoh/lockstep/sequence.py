"""What a participant believes of the steps it hears, beyond their run's barrier token: a step
follows from the previous one, and one that does not makes it ask the barrier's holder for the
current step with the whole key table (docs/security.md, "Lockstep and the clock").

On an open bus anybody can copy a real Step and change it. Were the largest step number heard
believed, one step numbered 10⁹ would raise the floor every later real step is refused under,
for the rest of the run; were a number taken only once, a forged step numbered as the next one
would shadow the real one (dropped as a duplicate) and could carry a table that makes every
later step unreadable. So:
* a step counts only if it is the next one in sequence (`number + 1`), or the same step again
  (a re-publication: same number, stamp, counts and table digest) — a step number far ahead is
  not believed, however plausible its time;
* anything that contradicts what this participant took — a step out of sequence, a second step
  under the number it took with other content, a step whose table it cannot read — makes it
  ask the barrier (a StepDone with `resync`), at most once per `ASK_AGAIN`;
* the barrier answers with its current step carrying the whole table, which the participant
  takes whatever its number, if it comes within `ANSWER_WITHIN` of the request. A forger who
  answers first (a second forged sample, sent when it sees the request) is taken instead; the
  next real step then contradicts it and the participant asks again.
A legitimate gap (a participant whose link was down while steps went out) heals the same way.
"""

from __future__ import annotations

from typing import Callable

from .protocol import REPORT_AFTER, Step

ASK_AGAIN = REPORT_AFTER       # wall s between two requests (the barrier honours one per this)
ANSWER_WITHIN = 2 * REPORT_AFTER  # wall s a whole step after a request is taken as its answer


def same_step(a: Step, b: Step) -> bool:
    """The same step again (a re-publication, whole or not), not another under its number."""
    return a.step == b.step and a.stamp == b.stamp and a.counts == b.counts and \
        a.table_digest == b.table_digest


class Sequence:
    """A participant's step numbers in one run: the last step it accepted, and whether it has
    asked the barrier for a whole step (and when)."""

    def __init__(self, wall: Callable[[], float]) -> None:
        self._wall = wall
        self.number = 0                   # the last step accepted
        self.last: Step | None = None     # … itself (a re-publication of it is nothing new)
        self.asked_at: float | None = None
        self.asks = 0                     # requests sent

    def restart(self, step: Step) -> None:
        """A new run begins with `step` (its first number is whatever the barrier counted)."""
        self.number, self.last, self.asked_at = step.step, step, None

    def again(self, step: Step) -> bool:
        return self.last is not None and same_step(step, self.last)

    def answers(self, step: Step) -> bool:
        """Is `step` the barrier's answer to this participant's request (a whole step soon
        after it)? Then it is taken whatever its number."""
        return step.base == 0 and self.asked_at is not None and \
            self._wall() - self.asked_at <= ANSWER_WITHIN

    def follows(self, step: Step) -> str | None:
        """None if `step` is the next one; otherwise why it is not believed."""
        if step.step == self.number + 1:
            return None
        if step.step > self.number + 1:
            return f"step {step.step} skips ahead of step {self.number}"
        return f"step {step.step} after step {self.number}"

    def accept(self, step: Step) -> None:
        self.number, self.last, self.asked_at = step.step, step, None

    def contradicted(self) -> bool:
        """Something contradicts what was taken: True if a request should go out now."""
        now = self._wall()
        if self.asked_at is not None and now - self.asked_at < ASK_AGAIN:
            return False
        self.asked_at = now
        self.asks += 1
        return True
