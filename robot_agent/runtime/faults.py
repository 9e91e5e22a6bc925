"""Fault injection in an agent (mrta_zenoh/failure.py: the grammar and the pure plan): what the
agent driver (loop.py) asks at its hooks, and nothing the driver needs otherwise.

In the driver because that is the one place every architecture's messages go out and come in
and its layers run, yet apart from it, so the driver reads as a driver and the injector is
tested alone on the in-process bus and a manual clock (tests/test_fault_injector.py). It holds
the run's plan, resolves a fault naming a robot by role, `@first`, at its time from the team's
announcements of their first assignments (mrta_zenoh/fault_roles.py: exact in lockstep), acts
on received coordination messages, and tallies what it did (mrta_zenoh/fault_tally.py):

* a crash (SIGKILL) and a stall (the layers stop, the decision logic and its messages go on)
  strike at their time: `strikes` says which, the driver does it (its crash hook, its layers);
* a partition: for a while nothing heard (`on_receipt`), and what the robot sends heard by
  nobody — each receiver drops it (`cut`), so the recording still holds what the robot said
  and did;
* loss drops on receipt (`on_receipt`), out-of-range drops at the tick in lockstep (`cut`:
  where both robots were at the message's stamp) and on receipt otherwise; latency delays a
  message's time heard (`on_receipt`) and is counted once the message is handled
  (`heard_late`).

The hooks, in the order a tick meets them: `listen` (at start), `on_receipt` (network threads),
`strikes` (each wake-up), `cut` and `heard_late` (per message handled at a tick), `announce`
(end of a tick), `tally` (after a decision tick), `restart` (time restarted), `final_tally`
(shutdown).
"""

from __future__ import annotations

import collections
import logging
import math
import threading
from typing import Callable

from mrta_zenoh import keys
from mrta_zenoh.bus import Bus, Sample
from mrta_zenoh.clock import EPSILON, Clock
from mrta_zenoh.failure import FaultKind, FaultPlan
from mrta_zenoh.fault_roles import EVERY_ASSIGNED, Assigned, assigned_key, first_assigned
from mrta_zenoh.fault_tally import TALLY_PERIOD, Cause, FaultTally, tally_key
from mrta_zenoh.keys import first_chunk
from mrta_zenoh.messages import Header, Odometry

from .inbox import is_due

MAX_ASSIGNED = 1_000  # robots whose first assignment is tracked: invented ids beyond are ignored
TRUTHS_KEPT = 32  # ground truths kept per robot (range:R): a message is judged at its own stamp


class FaultInjector:
    """One agent's fault injection. `plan` is the plan as resolved so far (an `@first` item
    becomes the robot's own fault, a peer's cut or nothing at its time); `given` the plan as
    given, which a restart of time resolves again. None: no fault touches this agent, and
    every hook is a no-op."""

    def __init__(self, robot_id: str, bus: Bus, clock: Clock, log: logging.Logger):
        self.robot_id, self.bus, self.clock, self.log = robot_id, bus, clock, log
        self.plan: FaultPlan | None = None
        self.given: FaultPlan | None = None
        # what injected faults did to coordination messages, by cause (fault_tally.Cause),
        # and what the robot last said of it (robotN/faults/tally) and when
        self.counts: collections.Counter[Cause] = collections.Counter()
        self._told_counts: dict[str, int] = {}
        self._told_at = -math.inf
        self._lock = threading.Lock()  # network callbacks run on several threads
        # drops decided on receipt (network threads), counted by the loop once due — at the
        # time they would have been heard, by the inbox's rule — so that in lockstep a tally at
        # time t holds exactly the drops of messages heard before t, whatever the threads did
        self._pending: collections.deque[tuple[float, Cause]] = collections.deque()
        # an @first fault: the team's first assignments heard (robot → stamp; callbacks write,
        # under _lock) and whether this robot announced its own
        self._assigned: dict[str, float] = {}
        self._announced = False
        # robot → its last ground truths (stamp, x, y), oldest first (range:R, `_pose_at`)
        self._where: dict[str, collections.deque[tuple[float, float, float]]] = {}

    def give(self, plan: FaultPlan | None) -> None:
        """The run's plan for this agent (mrta_zenoh.failure.plan_for), before `listen`."""
        self.plan = self.given = plan

    @property
    def delayed(self) -> bool:
        """Whether received messages wait for an injected latency (the inbox's due rule)."""
        return self.plan is not None and self.plan.latency is not None

    # ------------------------------------------------------------ at start
    def listen(self, roster: Callable[[], frozenset[str] | None]) -> list:
        """Subscribe to what the plan needs: the team's first assignments for an `@first`
        fault (only a robot on the `roster` counts, when there is one), every robot's ground
        truth for `range:R`. Returns the subscriptions, for the driver to close."""
        plan, handles = self.plan, []
        if plan is not None and plan.first is not None:
            handles.append(self.bus.subscribe(
                EVERY_ASSIGNED, lambda s: self._on_assigned(s, roster()), msg_type=Assigned))
        if plan is not None and plan.range is not None:
            handles.append(self.bus.subscribe(keys.ground_truth("*"), self._on_truth,
                                              msg_type=Odometry))
        return handles

    def _on_assigned(self, sample: Sample, roster: frozenset[str] | None) -> None:
        """A robot's first assignment (its own included). Only the earliest of a robot counts,
        from a sender its key and header agree on and, with a roster, on the team."""
        sender = first_chunk(sample.key)
        msg = sample.message
        if msg.header.frame_id.strip("/") != sender or (roster is not None
                                                         and sender not in roster):
            return
        with self._lock:
            if len(self._assigned) < MAX_ASSIGNED or sender in self._assigned:
                self._assigned[sender] = min(self._assigned.get(sender, msg.header.stamp),
                                             msg.header.stamp)

    def _on_truth(self, sample: Sample) -> None:
        """A robot's ground truth, for the range fault (failure.py, `range:R`)."""
        msg = sample.message
        robot = first_chunk(sample.key)
        poses = self._where.get(robot)
        if poses is None:
            if len(self._where) >= MAX_ASSIGNED:  # invented robots beyond: ignored
                return
            poses = self._where[robot] = collections.deque(maxlen=TRUTHS_KEPT)
        poses.append((msg.header.stamp, msg.pose.x, msg.pose.y))

    def _pose_at(self, robot: str, t: float) -> tuple[float, float] | None:
        """Where `robot` was at `t` (its latest ground truth stamped no later; the latest of
        all out of lockstep). Not simply the latest in lockstep: a message is judged on the
        network thread that delivers it, and the next step's ground truth may come in before
        it (the simulator's link is not the sender's; in an agent host, the host's own
        delivery may lag its answer to the step) — the range would then depend on the
        network's timing, where lockstep makes everything else depend on the seed alone."""
        poses = self._where.get(robot)
        if not poses:
            return None
        best = None
        for stamp, x, y in list(poses):
            if stamp <= t + EPSILON or best is None:
                best = (x, y)
            if stamp > t + EPSILON:
                break
        return best

    # ------------------------------------------------------------ on receipt (network threads)
    def on_receipt(self, key: str, seq: int, sender: str, heard: float) -> float | None:
        """A teammate's coordination message, from `sender` on `key` with sequence number
        `seq`, that would count as heard at `heard`: None if a fault drops it (counted once
        due), else when it counts as heard (later by an injected latency)."""
        plan = self.plan
        if plan is None or not plan.channel:
            return heard
        if plan.lost(key, seq):
            return self._drop(heard, Cause.LOST)
        heard += plan.delay(key, seq)
        if plan.cut_off(heard):
            return self._drop(heard, Cause.CUT_OFF)
        # range: here only out of lockstep (where both are now); in lockstep at the tick (`cut`)
        if not self.clock.in_lockstep() and plan.out_of_range(
                self._pose_at(self.robot_id, math.inf), self._pose_at(sender, math.inf)):
            return self._drop(heard, Cause.OUT_OF_RANGE)
        return heard

    def _drop(self, heard: float, cause: Cause) -> None:
        with self._lock:
            self._pending.append((heard, cause))

    # ------------------------------------------------------------ at the loop's wake-ups
    def strikes(self, now: float) -> FaultKind | None:
        """What strikes this agent now: CRASH or STALL (the driver does it; a stall is said
        at every wake-up from its time on), else None. An `@first` fault whose time has come is
        resolved first."""
        plan = self.plan
        if plan is None:
            return None
        if plan.first is not None and now >= plan.first.at:
            plan = self.resolve_first(now)
        if plan.crashed(now):
            return FaultKind.CRASH
        if plan.stalled(now):
            return FaultKind.STALL
        return None

    def resolve_first(self, now: float) -> FaultPlan:
        """The @first fault's time has come: strike it if this robot was first assigned
        (fault_roles.first_assigned over what was heard stamped before it), else drop it."""
        plan = self.plan
        with self._lock:
            heard = dict(self._assigned)
        who = first_assigned(heard, plan.first.at, plan.taken)
        self.log.info("%s: %s at t=%.2f is %s", self.robot_id, plan.first.spec, now,
                      who or "nobody (no robot was assigned before)")
        self.plan = plan.resolved(who)
        return self.plan

    def cut(self, sender: str, stamp: float, heard: float) -> bool:
        """Whether a message `sender` sent at `stamp`, heard at `heard`, is dropped (counted) by
        a partition — its sender's, or this robot's own — or, in lockstep, by the range.

        At the tick, not on receipt: an `@first` partition is resolved by then. This robot's
        own partition is also applied on receipt (`on_receipt`), which is all a partition named
        in the spec needs; checked here again, it catches what arrived before an `@first`
        partition struck this robot — a teammate's message stamped at the fault's very time
        races the loop's resolution, and what was heard, and the tally, changed from run to run
        of one seed.

        The range in lockstep, at the tick too: a message is judged by where both robots were
        at its stamp (their ground truths), and only at the tick are those sure to be here —
        lockstep holds every step until the simulator's samples of the steps before have
        arrived, but a teammate's message may arrive before them. Judged on receipt, a message
        from another process could meet the receiver's truths one step behind, one in the same
        agent host never (the host resumes its robots once the step's truths are in): MURDOCH
        under range:4 ended a task a tick apart in the two layouts (issue 47's identity)."""
        plan = self.plan
        if plan is None:
            return False
        if plan.cut_off(heard) or (plan.peers_cut and plan.sender_cut(sender, stamp)):
            self.counts[Cause.CUT_OFF] += 1
            return True
        if plan.range is not None and self.clock.in_lockstep() and plan.out_of_range(
                self._pose_at(self.robot_id, stamp), self._pose_at(sender, stamp)):
            self.counts[Cause.OUT_OF_RANGE] += 1
            return True
        return False

    def heard_late(self, key: str, seq: int) -> None:
        """A message from a teammate is handled: count it if an injected latency delayed it."""
        plan = self.plan
        if plan is not None and plan.latency is not None and plan.delay(key, seq) > 0:
            self.counts[Cause.DELAYED] += 1  # heard late, and heard

    def announce(self, now: float, task: str | None) -> None:
        """With an @first fault in the run, say once when this robot first holds a task."""
        if self._announced or self.given is None or self.given.first is None or task is None:
            return
        self._announced = True
        self.bus.publish(assigned_key(self.robot_id),
                         Assigned(header=Header(frame_id=self.robot_id, stamp=now, seq=1),
                                  task_id=task))

    # ------------------------------------------------------------ the tally
    @property
    def dropped(self) -> int:
        """Coordination messages injected faults kept from this robot (delays not counted)."""
        self._settle(self.clock.now(), everything=True)
        return sum(n for cause, n in self.counts.items() if cause is not Cause.DELAYED)

    def _settle(self, now: float, everything: bool = False) -> None:
        """Count the drops due at `now` (the inbox's rule; `everything`: all of them)."""
        lockstep, delayed = self.clock.in_lockstep(), self.delayed
        with self._lock:
            pending = list(self._pending)
            self._pending.clear()
        later = []
        for heard, cause in pending:
            if not everything and not is_due(heard, now, lockstep, delayed):
                later.append((heard, cause))
            else:
                self.counts[cause] += 1
        if later:
            with self._lock:
                self._pending.extend(later)

    def tally(self, now: float, final: bool = False) -> None:
        """Say what injected faults did to this robot's messages (mrta_zenoh.fault_tally), when
        it changed — at most every TALLY_PERIOD, or now as the robot stops. Nothing without a
        plan."""
        if self.given is None or (not final and now < self._told_at + TALLY_PERIOD):
            return
        self._settle(now)
        counts = {cause.value: self.counts[cause] for cause in Cause}
        if counts == self._told_counts or not any(counts.values()):
            return
        self._told_counts, self._told_at = counts, now
        header = Header(frame_id=self.robot_id, stamp=now, seq=1)
        self.bus.publish(tally_key(self.robot_id), FaultTally(header=header, **counts))

    def final_tally(self) -> None:
        """The robot stops: say the tally once more."""
        self.tally(self.clock.now(), final=True)

    def restart(self) -> None:
        """Time restarted (a new simulation run): the plan as given (an @first fault is
        resolved again), the tally from the run's start, no first assignment heard yet."""
        self.plan = self.given
        with self._lock:
            self.counts.clear()
            self._pending.clear()
            self._assigned.clear()
        self._told_counts, self._told_at = {}, -math.inf
        self._announced = False
