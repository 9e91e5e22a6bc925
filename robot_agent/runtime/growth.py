"""Tasks submitted at run time, as a robot's agent takes them (issue 50; docs/tasks.md): the
driver (loop.Agent) hears the intake's `tasks/change`, and at a decision step grows what the
robot knows — its instance, its plugins, its decision logic — by the tasks that entered.

* **Whom it believes.** A change counts only from the intake: `header/frame_id` is `tasks`
  (mrta_zenoh.tasks.messages.INTAKE). On a secured fleet only the intake's certificate may
  publish on `tasks/change` (its role, mrta_zenoh.tasks.server.secure_role): a robot, an
  observer or a submitter cannot make a task enter, whatever it says; on an open bus a forger
  can, as it can say anything else. Anything else on the key is counted (`not_intake`) and
  dropped, as is a change for a task the robot knows already (`known_task`) or whose fields its
  application refuses (`refused_fields`: the intake checked them with the same rules, so only a
  forgery gets there).
* **When.** A change stamped at instant T is taken at the robot's first decision step after T
  — as cancellations are (configs/applications/delivery/board.py): in lockstep every process
  has received it before its time moves past T, but one ticking at T itself may not have yet,
  so the next tick, the same for every robot and the dispatcher. Taken after the step's
  messages (all stamped before the growth, counting tasks as before) and before the logic's
  tick. Out of lockstep: the first step after it arrived.
* **What grows.** The robot's instance document (`InstanceKind.grow`: the task arriving at
  the instant it entered), its plugins (`Plugins.grow`: the new task's evaluator and layers,
  of the classes its first task that takes submitted tasks uses), then the logic, told through
  its no-op hooks (`Coordinator.tasks_added`, `task_priority`, `task_cancelled`), each with
  the instant the change entered. A logic planning on the instance's `Problem` grows it with
  `Growth.problem` (only the new distances computed).
"""

from __future__ import annotations

import collections
import dataclasses
import json
import logging
import threading
from typing import TYPE_CHECKING, Any, NamedTuple

from mrta_zenoh import instances
from mrta_zenoh.bus import Bus, Sample, Subscription
from mrta_zenoh.clock import EPSILON, Clock
from mrta_zenoh.errors import ConfigError
from mrta_zenoh.tasks.messages import CHANGE, INTAKE, Change, Op
from mrta_zenoh.untrusted import visible

if TYPE_CHECKING:
    from .coordinator import Coordinator
    from .plugins import AgentContext, Plugins

KIND = "task_change"           # the refusal tally's kind for what is refused here
NOT_INTAKE = "not_intake"      # a change not from the intake
KNOWN_TASK = "known_task"      # a task the robot knows already
REFUSED_FIELDS = "refused_fields"  # fields its application refuses
PENDING = 100_000              # changes waiting for the next step at most (the intake's bound)


class NewTask(NamedTuple):
    """A task that entered the run: its id, the instant it entered, its priority (higher is
    more urgent) and who submitted it."""

    id: str
    at: float
    priority: int = 0
    submitter: str = ""


@dataclasses.dataclass
class Growth:
    """The tasks that entered at one step, and the robot's instance with them."""

    tasks: tuple[NewTask, ...]
    instance: instances.Loaded
    _grown: tuple[Any, Any] | None = None

    def problem(self, before: Any) -> Any:
        """The planning problem `before` grown by these tasks (InstanceKind.grown_problem),
        computed once whoever of the agent's logics asks."""
        if self._grown is None or self._grown[0] is not before:
            self._grown = (before, self.instance.kind.grown_problem(self.instance.doc, before))
        return self._grown[1]


class _Heard(NamedTuple):
    at: float
    change: Change


class RunTimeTasks:
    """One agent's side of tasks at run time (module docstring)."""

    def __init__(self, robot_id: str, clock: Clock, log: logging.Logger):
        self.robot_id = robot_id
        self.clock = clock
        self.log = log
        self._lock = threading.Lock()
        self._pending: collections.deque[_Heard] = collections.deque(maxlen=PENDING)
        self.refused: collections.Counter[tuple[str, str, str, bool]] = collections.Counter()
        # what the logic was told so far, in order (a logic built afresh is told again)
        self.told: list[tuple[str, tuple]] = []

    def listen(self, bus: Bus) -> Subscription:
        return bus.subscribe(CHANGE, self._on_change, msg_type=Change)

    def refusals(self) -> dict:
        with self._lock:
            return dict(self.refused)

    def _on_change(self, sample: Sample) -> None:
        msg = sample.message
        with self._lock:
            if msg.header.frame_id != INTAKE:
                self.refused[(KIND, "-", NOT_INTAKE, True)] += 1  # bounded: no name kept
                return
            lockstep = self.clock.in_lockstep()
            self._pending.append(_Heard(msg.header.stamp if lockstep else self.clock.now(), msg))

    def due(self, now: float) -> list[Change]:
        """The changes to take at the step at `now` (module docstring, "When"), in the order
        they entered (their instant, then the intake's sequence)."""
        with self._lock:
            due = [h for h in self._pending if h.at + EPSILON < now]
            if not due:
                return []
            self._pending = collections.deque((h for h in self._pending
                                               if not h.at + EPSILON < now), maxlen=PENDING)
        return [h.change for h in sorted(due, key=lambda h: (h.change.header.stamp,
                                                             h.change.header.seq))]

    def take(self, now: float, plugins: Plugins, ctx: AgentContext,
             coordinator: Coordinator) -> None:
        """Grow by the changes due at `now` (module docstring, "What grows")."""
        changes = self.due(now)
        if not changes:
            return
        loaded = plugins.instance
        new: list[NewTask] = []
        for c in changes:
            if c.op != Op.SUBMIT or loaded is None:
                continue
            if c.task_id in loaded.kind.tasks(loaded.doc):
                self._refuse(KNOWN_TASK, c)
                continue
            try:
                fields = json.loads(c.fields or "{}")
                if not isinstance(fields, dict):
                    raise ConfigError("fields: not a JSON object")
                doc = loaded.kind.grow(loaded.doc, c.task_id, fields, c.header.stamp)
            except (ConfigError, ValueError) as exc:
                self._refuse(REFUSED_FIELDS, c)
                self.log.warning("%s: task %s entered the run with fields this robot refuses: "
                                 "%s", self.robot_id, visible(c.task_id, 80), exc)
                continue
            loaded = dataclasses.replace(loaded, doc=doc)
            new.append(NewTask(c.task_id, c.header.stamp, c.priority, c.submitter))
        if new:
            plugins.instance = loaded
            ctx.instance = loaded.doc
            plugins.grow([t.id for t in new], ctx)
            self._tell(coordinator, "tasks_added", Growth(tuple(new), loaded), now)
        for c in changes:
            if c.op == Op.REPRIORITIZE:
                self._tell(coordinator, "task_priority", c.task_id, c.priority, now)
            elif c.op == Op.CANCEL:
                self._tell(coordinator, "task_cancelled", c.task_id, now)

    def _tell(self, coordinator: Coordinator, hook: str, *args) -> None:
        self.told.append((hook, args))
        getattr(coordinator, hook)(*args)  # a Coordinator hook by name (every one has it)

    def retell(self, coordinator: Coordinator) -> None:
        """A logic built afresh (time restarted) is told every change so far, in order."""
        for hook, args in self.told:
            getattr(coordinator, hook)(*args)

    def _refuse(self, reason: str, c: Change) -> None:
        with self._lock:
            self.refused[(KIND, INTAKE, reason, True)] += 1

