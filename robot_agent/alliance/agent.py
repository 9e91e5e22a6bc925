"""ALLIANCE's decision logic for one robot, as the agent runtime drives it: the high level
(`HighLevel`, pure logic on virtual time) fed with sensory feedback from the evaluator plugins
and with teammates' broadcasts, and what it says back — sensory feedback and motivations every
tick (monitoring: lossy, and watched only — no teammate decides on them, so lockstep does not
wait for them), a broadcast of the active task at `broadcast_rate` (coordination).

The driver (mrta_agent.runtime.loop.Agent) owns the inbox, the team, sender checks, headers and
layers; this class only decides.
"""

from __future__ import annotations

import collections
import logging
from typing import Iterable

from mrta_zenoh.clock import EPSILON
from mrta_zenoh.keys import task_chunk
from mrta_zenoh.timetext import at

from ..runtime.coordinator import Coordinator
from ..runtime.loop import Say
from ..runtime.plugins import Plugins
from .high_level import HighLevel, TaskSwitch
from .params import AgentParams

log = logging.getLogger("mrta.agent")
HISTORY = 256  # decisions kept for inspection (tests, a debugger): bounded, a robot runs for days


class AllianceCoordinator(Coordinator):
    listens = ("inter_robot_communication",)

    def __init__(self, robot_id: str, params: AgentParams, plugins: Plugins):
        self.robot_id = robot_id
        self.params = params
        self.plugins = plugins
        self.high = HighLevel(robot_id, params.robot)
        self.history: collections.deque[tuple[float, TaskSwitch]] = \
            collections.deque(maxlen=HISTORY)
        self._last_broadcast: float | None = None
        self._was_active: dict[str, bool] = {}

    @property
    def active_task(self) -> str | None:
        return self.high.active_task

    def teammate(self, robot: str, alive: bool) -> None:
        """Teammates matter to ALLIANCE only through their broadcasts (and their lapse)."""

    def hear(self, kind: str, sender: str, msg, at: float) -> bool:
        return self.high.on_broadcast(sender, msg.task_id, msg.expected_duration, at,
                                      msg.active_since)

    def tick(self, now: float) -> Iterable[Say]:
        out: list[Say] = []
        for task, ev in self.plugins.evaluators.items():
            applicable = bool(ev.is_applicable(now))
            self.high.on_feedback(task, applicable, now)
            out.append(Say("sensory_feedback", dict(task_id=task, applicable=applicable),
                           lossy=True, watched=True))
        before = self.high.active_task
        states, transitions = self.high.tick(now)
        for st in states:
            # monitoring, so lossy — except the sample where `active` changes, which says who
            # does what (the mission's ground truth, ground_truth.py): that one must arrive
            changed = self._was_active.get(st.task_id) != st.active
            self._was_active[st.task_id] = st.active
            out.append(Say("motivation", dict(task_id=st.task_id, impatience=st.impatience,
                                              acquiescent=st.acquiescent,
                                              suppressed=st.suppressed, resetted=st.resetted,
                                              applicable=st.applicable,
                                              motivation=st.motivation,
                                              threshold=st.threshold, active=st.active),
                           subkey=task_chunk(st.task_id), lossy=not changed, watched=True))
        for tr in transitions:
            self.history.append((now, tr))
            if tr.kind == "reset":
                log.info("%s: motivation for %s reset (%s) %s", self.robot_id,
                         tr.task_id, tr.reason, at(now))
            else:
                log.info("%s: %s %s (%s) %s", self.robot_id, tr.kind, tr.task_id,
                         tr.reason, at(now))
        after = self.high.active_task
        if after != before and after is not None:
            self._last_broadcast = None  # announce a new activation at once
        out += self._broadcast(now)
        return out

    def _broadcast(self, now: float) -> list[Say]:
        task = self.high.active_task
        if task is None:
            return []
        period = 1.0 / self.params.robot.broadcast_rate
        if self._last_broadcast is not None and now - self._last_broadcast < period - EPSILON:
            return []
        self._last_broadcast = now
        return [Say("inter_robot_communication",
                    dict(task_id=task,
                         expected_duration=self.high.sets[task].params.expected_duration,
                         active_since=self.high.active_since()))]
