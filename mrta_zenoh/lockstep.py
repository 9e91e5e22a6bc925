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
  publishes `Step(stamp, step, sent)` reliably on `@mrta/lockstep/step`.
* A participant's time moves to `stamp` only once it has received every sample the other
  participants had published before their last acknowledgement (`sent`: cumulative counts per
  key, for the keys it subscribes to). That is what makes a broadcast from robot A, sent while
  A handled step k, reach robot B before B handles step k+1, whatever the network's scheduling.
* When the participant has nothing more to do at that time — its main loop would wait for a
  later time — it publishes `StepDone(participant, stamp, sent, next)` on
  `@mrta/lockstep/done/<id>`: its commands of that step went out before it, on the same link,
  and `next` is the time it waits for. The simulator stops only at steps where some
  participant has something due (an agent at 10 Hz: every fifth 20 ms step), so lockstep costs
  one round trip per participant tick, not per physics step.
* The simulator steps again once every participant is done and it has taken their commands
  of that step into account (counted as for the participants). A participant alive but silent for `timeout` wall seconds is reported (a log line
  and `lockstep/status`, which the supervisor shows as an alarm) and no longer waited for,
  until it answers again.
"""

from __future__ import annotations

import contextlib
import logging
import threading
import time
from typing import Callable

from .clock import EPSILON, SimClock
from .messages import Finite, Message, message

log = logging.getLogger("mrta.lockstep")

STEP = "@mrta/lockstep/step"
DONE = "@mrta/lockstep/done"           # /<participant>
PARTICIPANT = "@mrta/lockstep/participant"  # /<participant>: liveliness
BARRIER = "@mrta/lockstep/barrier"      # /<run>: liveliness of a lockstep simulator
STATUS = "lockstep/status"


@message("mrta_msgs/Step")
class Step(Message):
    stamp: Finite
    step: int
    sent: dict[str, int]


@message("mrta_msgs/StepDone")
class StepDone(Message):
    """Done with `stamp`; nothing to do before `next` (-1: unknown), so the simulator need not
    stop for this participant at the steps in between."""

    participant: str
    stamp: Finite
    sent: dict[str, int]
    next: Finite = -1.0


@message("mrta_msgs/LockstepStatus")
class LockstepStatus(Message):
    """Participants the simulator stopped waiting for (alive, but silent past the timeout)."""

    stamp: Finite
    unresponsive: tuple[str, ...]


class LockstepClock(SimClock):
    """A participant's clock: simulation time that also moves in lockstep when the simulator
    runs it (and follows the plain `clock` key otherwise)."""

    def __init__(self, participant: str) -> None:
        super().__init__()
        self.participant = participant
        self.lockstep = threading.Event()
        self._bus = None
        self._pending: Step | None = None
        self._acked = True
        self._sleeping_until: float | None = None  # the main loop waits for this time
        self._publish_done: Callable[[float, float], None] | None = None

    def join(self, bus) -> contextlib.ExitStack:
        """Count traffic, follow steps, and announce the participant; returns the handles as
        one ExitStack (closing it leaves the barrier)."""
        self._bus = bus
        bus.counting = True
        done_key = f"{DONE}/{self.participant}"

        def publish_done(stamp: float, next_due: float) -> None:
            bus.publish(done_key, StepDone(self.participant, stamp, dict(bus.sent_counts),
                                           next_due))

        self._publish_done = publish_done
        handles = [bus.subscribe(STEP, self._on_step, msg_type=Step),
                   # a lockstep simulator announces itself before its first clock sample: from
                   # then on only steps move time (the clock would run ahead of the sensors)
                   bus.watch_liveliness(f"{BARRIER}/*", self._on_barrier)]
        # while steps are pending, every received sample may be the one they wait for
        bus.on_counted = self._release
        handles.append(bus.declare_token(f"{PARTICIPANT}/{self.participant}"))
        stack = contextlib.ExitStack()
        for h in handles:
            stack.callback(h.close)
        return stack

    def _on_barrier(self, key: str, alive: bool) -> None:
        if alive:
            self.lockstep.set()

    def on_clock(self, stamp: float, source: str = "") -> bool:
        if self.lockstep.is_set():
            return False  # steps, not the lossy clock, move time in lockstep
        return super().on_clock(stamp, source)

    def _on_step(self, sample) -> None:
        with self._cond:
            self.lockstep.set()
            self._pending = sample.message
        self._release()

    def _release(self) -> None:
        """Move time to the pending step once everything it requires has arrived. If the main
        loop is already waiting for a later time, it has nothing to do now: done at once."""
        with self._cond:
            step = self._pending
            if step is None or not self._bus.received_all(step.sent):
                return
            self._pending = None
            if step.stamp < self._now:  # a new run (time restarted): adopt it
                self.restarts += 1
            self._now = step.stamp
            idle = self._sleeping_until is not None and \
                self._sleeping_until > step.stamp + EPSILON
            self._acked = idle
            self._last_wall = self._wall()
            self._cond.notify_all()
        self.started.set()
        if idle:
            self._publish_done(step.stamp, self._sleeping_until)

    def sleep_until(self, t: float, stop: threading.Event | None = None) -> bool:
        """Before waiting for a later time, tell the simulator this participant is done with
        the current one (its commands were published before, on the same link)."""
        with self._cond:
            if t > self._now + EPSILON and not self._acked and self._publish_done is not None:
                self._acked = True
                stamp = self._now
            else:
                stamp = None
            self._sleeping_until = t
        if stamp is not None:
            self._publish_done(stamp, t)
        try:
            return super().sleep_until(t, stop)
        finally:
            with self._cond:
                self._sleeping_until = None


class Barrier:
    """The simulator's side: whom to wait for, and waiting. A context manager: leaving it
    withdraws the barrier's token and subscriptions (close())."""

    def __init__(self, bus, run_id: str, timeout: float = 5.0):
        self.bus = bus
        self.timeout = timeout
        self.participants: set[str] = set()
        self.done: dict[str, StepDone] = {}
        self.unresponsive: set[str] = set()
        self._cond = threading.Condition()
        self._changed, self._changed_at = 0, time.monotonic()
        bus.counting = True  # set before the commands' subscription (SimNode) exists
        bus.on_counted = self._poke
        self.handles = [
            bus.watch_liveliness(f"{PARTICIPANT}/*", self._on_participant),
            bus.subscribe(f"{DONE}/*", self._on_done, msg_type=StepDone),
            bus.declare_token(f"{BARRIER}/{run_id}"),
        ]
        self.step = 0

    def settle(self, quiet: float = 0.5, limit: float = 3.0) -> None:
        """Give participants that are already up the time to be heard: until the set has not
        changed for `quiet` seconds (a new session first has to reach every peer)."""
        deadline = time.monotonic() + limit
        with self._cond:
            while time.monotonic() < deadline:
                changed = self._changed
                self._cond.wait(min(quiet, max(0.0, deadline - time.monotonic())))
                if self._changed == changed and time.monotonic() - self._changed_at >= quiet:
                    return

    def _on_participant(self, key: str, alive: bool) -> None:
        name = key.rsplit("/", 1)[-1]
        with self._cond:
            self._changed += 1
            self._changed_at = time.monotonic()
            (self.participants.add if alive else self.participants.discard)(name)
            if not alive:
                self.done.pop(name, None)
                self.unresponsive.discard(name)
            self._cond.notify_all()

    def _on_done(self, sample) -> None:
        with self._cond:
            self.done[sample.message.participant] = sample.message
            self._cond.notify_all()

    def sent(self) -> dict[str, int]:
        """What the next step requires: the simulator's own samples (sensor data: on the same
        link as the step, but Zenoh may run the callbacks of two subscriptions concurrently)
        and every participant's, cumulative counts per key."""
        out: dict[str, int] = dict(self.bus.sent_counts)
        with self._cond:
            for d in self.done.values():
                for k, n in d.sent.items():
                    out[k] = max(out.get(k, 0), n)
        return out

    def _poke(self) -> None:
        with self._cond:
            self._cond.notify_all()

    def due(self, stamp: float) -> bool:
        """Must the simulator stop at `stamp`? Yes if a participant has something to do by
        then (or has not said); the steps in between run without a round trip."""
        with self._cond:
            for p in self.participants:
                if p in self.unresponsive:
                    continue
                d = self.done.get(p)
                if d is None or d.next < 0 or d.next <= stamp + EPSILON:
                    return True
        return False

    def publish(self, stamp: float) -> None:
        self.step += 1
        self.bus.publish(STEP, Step(stamp, self.step, self.sent()))

    def wait(self, stamp: float, stop: threading.Event) -> None:
        """Until every participant is done with `stamp` and its commands of that step have been
        taken into account here (the counts in its StepDone; Zenoh may run two subscriptions'
        callbacks out of order) — or the participant is given up for this time; it rejoins
        when it answers again."""
        deadline = time.monotonic() + self.timeout
        with self._cond:
            while not stop.is_set():
                waiting = {p for p in self.participants
                           if p not in self.unresponsive and
                           (p not in self.done or self.done[p].stamp < stamp)}
                back = {p for p in self.unresponsive
                        if p in self.done and self.done[p].stamp >= stamp}
                if back:
                    self.unresponsive -= back
                    log.warning("lockstep: %s answers again", ", ".join(sorted(back)))
                    self._status(stamp)
                if not waiting and self.bus.received_all(self.sent()):
                    return
                remaining = deadline - time.monotonic()
                if remaining <= 0:
                    self.unresponsive |= waiting
                    log.warning("lockstep: %s did not finish t=%.2f within %.1f s: no longer "
                                "waited for", ", ".join(sorted(waiting)), stamp, self.timeout)
                    self._status(stamp)
                    return
                self._cond.wait(min(remaining, 0.05))

    def _status(self, stamp: float) -> None:
        self.bus.publish(STATUS, LockstepStatus(stamp, tuple(sorted(self.unresponsive))))

    def close(self) -> None:
        for h in self.handles:
            h.close()

    def __enter__(self) -> "Barrier":
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
