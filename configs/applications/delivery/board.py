"""What one robot knows of the team's deliveries: which tasks are done, by whom. Shared by the
robot's delivery plugins (every task's evaluator and layer), so a completion is known to all of
them at once — the robot's own from its layer directly, a teammate's from its `done` message.

A `done` counts only on its sender's own key with a matching `header/frame_id` (a sample on
robot1's key claiming to be robot2 says nothing); anything else is counted and dropped.
"""

from __future__ import annotations

import threading

from mrta_zenoh.keys import first_chunk
from mrta_agent.runtime.plugins import Plugin

from .keys import ALL_DONE, Event
from .messages import TaskEvent

ATTRIBUTE = "delivery.board"  # its key on the robot's blackboard (AgentContext.share)


class Board:
    def __init__(self, owner: Plugin):
        self.robot_id = owner.ctx.robot_id
        self._lock = threading.Lock()
        self.done: dict[str, tuple[str, float]] = {}   # task → (robot, stamp)
        self.rejected = 0
        owner.subscribe(ALL_DONE, self._on_done, msg_type=TaskEvent)

    @classmethod
    def of(cls, owner: Plugin) -> "Board":
        """The robot's board, made by the first delivery plugin set up (which then owns its
        subscription: plugins are shut down together)."""
        return owner.ctx.share(ATTRIBUTE, lambda: cls(owner))

    def _on_done(self, sample) -> None:
        msg = sample.message
        sender = first_chunk(sample.key)
        if msg.event != Event.DONE or msg.header.frame_id.strip("/") != sender:
            with self._lock:
                self.rejected += 1
            return
        self.mark_done(msg.task_id, sender, msg.header.stamp)

    def mark_done(self, task_id: str, robot: str, stamp: float) -> None:
        with self._lock:
            self.done.setdefault(task_id, (robot, stamp))

    def is_done(self, task_id: str) -> bool:
        with self._lock:
            return task_id in self.done

    def delivered_by(self, robot: str) -> int:
        """How many deliveries `robot` has completed (an instance's max_tasks_per_robot caps
        them)."""
        with self._lock:
            return sum(1 for r, _ in self.done.values() if r == robot)
