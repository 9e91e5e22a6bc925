"""What one robot knows of the team's deliveries: which tasks are done, by whom. Shared by the
robot's delivery plugins (every task's evaluator and layer), so a completion is known to all of
them at once — the robot's own from its layer directly, a teammate's from its `done` message.

A `done` counts only on its sender's own key with a matching `header/frame_id` (a sample on
robot1's key claiming to be robot2 says nothing); anything else is counted and dropped. A
teammate's `done` is believed only after its own `started` for the task, a service before, at a
time it could have reached the task (done_rule.py); a `done` on this robot's own key that it
never said is not believed either. What is not believed is in the robot's refusal tally
(AgentContext.refusal_sources), so the run's summary names it.

It also knows the tasks cancelled at run time (mrta_zenoh.tasks: the intake's `tasks/change`),
each from the instant after the one the change was stamped with: in lockstep every process has
received a change before its time moves past that instant, but one ticking at that very instant
may or may not have yet — so a cancellation counts from the next tick on, the same for all.
"""

from __future__ import annotations

import threading

from mrta_zenoh.clock import EPSILON
from mrta_zenoh.keys import first_chunk
from mrta_zenoh.tasks.messages import CHANGE, INTAKE, Change, Op
from mrta_agent.runtime.plugins import Plugin

from .done_rule import KIND, NOT_OWN, DoneRule
from .keys import ALL_DONE, ALL_STARTED, Event
from .messages import TaskEvent

ATTRIBUTE = "delivery.board"  # its key on the robot's blackboard (AgentContext.share)
PATHS = "delivery.paths"  # the world's path map on the blackboard (layers.path_map_of)


class Board:
    def __init__(self, owner: Plugin):
        self.robot_id = owner.ctx.robot_id
        self._lock = threading.Lock()
        self.done: dict[str, tuple[str, float]] = {}   # task → (robot, stamp)
        self.rejected = 0
        instance = owner.ctx.instance
        self.rule = DoneRule(instance, owner.ctx.share(PATHS, instance.path_map))
        self.own: set[str] = set()  # tasks this robot served itself
        self.cancelled: dict[str, float] = {}          # task → the instant it was cancelled
        owner.ctx.refusal_sources.append(self.refusals)
        owner.subscribe(ALL_DONE, self._on_event, msg_type=TaskEvent)
        owner.subscribe(ALL_STARTED, self._on_event, msg_type=TaskEvent)
        owner.subscribe(CHANGE, self._on_change, msg_type=Change)

    @classmethod
    def of(cls, owner: Plugin) -> "Board":
        """The robot's board, made by the first delivery plugin set up (which then owns its
        subscription: plugins are shut down together)."""
        return owner.ctx.share(ATTRIBUTE, lambda: cls(owner))

    def _on_event(self, sample) -> None:
        msg = sample.message
        sender = first_chunk(sample.key)
        if msg.event != sample.key.rsplit("/", 1)[-1] or msg.header.frame_id.strip("/") != sender:
            with self._lock:
                self.rejected += 1
            return
        task, stamp = msg.task_id, msg.header.stamp
        with self._lock:
            if sender == self.robot_id:  # its own completions it knows without hearing them
                if msg.event == Event.DONE and task not in self.own:
                    self.rule.refused[(KIND, sender, NOT_OWN, True)] += 1
                return
            if msg.event == Event.STARTED:
                done = self.rule.on_started(sender, task, stamp)
            else:
                done = stamp if self.rule.on_done(sender, task, stamp) else None
            if done is not None:
                self.done.setdefault(task, (sender, done))

    def refusals(self) -> dict:
        with self._lock:
            return self.rule.refusals()

    def _on_change(self, sample) -> None:
        msg = sample.message
        if msg.op == Op.CANCEL and msg.header.frame_id == INTAKE:
            with self._lock:
                self.cancelled.setdefault(msg.task_id, msg.header.stamp)

    def is_cancelled(self, task_id: str, now: float) -> bool:
        """Cancelled before `now` (module docstring: from the tick after its instant)."""
        with self._lock:
            at = self.cancelled.get(task_id)
        return at is not None and now > at + EPSILON

    def mark_done(self, task_id: str, robot: str, stamp: float) -> None:
        with self._lock:
            if robot == self.robot_id:
                self.own.add(task_id)
            self.done.setdefault(task_id, (robot, stamp))

    def is_done(self, task_id: str, now: float) -> bool:
        """Done by this robot, or by a teammate before `now`: a teammate's `done` counts from
        the tick after its instant, as a cancellation does (module docstring). Counted at its
        own instant, it reached a robot ticking then in one process and not in another: under
        MURDOCH range:4 (seed 3) robot2's `done` of t4 stamped 11.9 started robot5's stall of
        the same task at 11.9 or 12.0 from run to run of one process per robot (its release at
        14.9 or 15.0), and always at 11.9 in a host (issue 47's identity)."""
        with self._lock:
            who = self.done.get(task_id)
        return who is not None and (who[0] == self.robot_id or now > who[1] + EPSILON)

    def done_by_teammate(self, task_id: str, now: float) -> bool:
        """Done, as believed, by another robot than this one, before `now` (`is_done`)."""
        with self._lock:
            who = self.done.get(task_id)
        return who is not None and who[0] != self.robot_id and now > who[1] + EPSILON

    def delivered_by(self, robot: str) -> int:
        """How many deliveries `robot` has completed (an instance's max_tasks_per_robot caps
        them)."""
        with self._lock:
            return sum(1 for r, _ in self.done.values() if r == robot)
