"""A robot serving the route its *own* decision logic keeps (SSI's auction wins, CBBA's bundle):
the thin adapter between a pure logic (a `RouteLogic`: `listens`, `hear`, `teammate`,
`tick(now) -> [Say]`, `route()`, `served(task, at)`) and the `RouteExecutor`. The logic decides;
this class only carries its messages, hands its route to the executor once the logic says it is
*settled*, feeds served tasks back, watches its teammates' progress and reports its own.

Rules, each for a reason:

* **Settled before setting off.** The executor takes the logic's route only while the logic is
  settled (`settled(now)`: SSI — no task any live robot could serve is still open; CBBA — its
  winning-bid table unchanged for `settle` seconds). With every task known at the start the team
  therefore sets off on the converged plan, not on a prefix of it the next round reorders; the
  executed orders equal the converged ones. Mid-run (an arrival, a loss) a robot finishes the
  task it is on meanwhile and takes the new route when the logic settles again.
* **Work in progress is kept.** The task the robot set off to stays first (RouteExecutor.assign)
  even if the logic's path would now insert a task before it — a departure from SSI's and
  CBBA's insertion, whose bids assume the robot can still change its next stop.
* **A stalled teammate is a departed one.** A teammate whose `Progress` reports show a task but
  neither motion, nor a task served, nor a change of task for `progress_timeout` seconds is
  told to the logic as gone (`teammate(robot, False)`), exactly as if its token went: its tasks
  are auctioned again (SSI) or its wins reset (CBBA). When it is seen to move again (or its
  token comes back after going) it is told as back — moved, not merely changed task: a robot
  stripped of its tasks changes task without moving, and was told back at once, won tasks
  again and stalled on them again, one `progress_timeout` after another (as central's
  dispatcher rules, issue 51.2). A stalled robot keeps talking, but its teammates
  no longer count what it says. The logic knows which of its gone teammates are stalled
  (`RouteLogic.declared`), and says so in its messages (SSI's `Round.out`, CBBA's `Bids.out`):
  what the summary's declared stalls are read from (issue 51.2: only central's were named).
* **Waiting is not stalling** (issue 49). The `progress_timeout` runs from the later of its last
  progress and its task's window opening and, once it is at the task, beyond the task's service:
  a robot early at a windowed task stands there until the window opens, then serves it (the
  delivery layer), and is making the progress its plan asks. Not before its task arrived either.
  Central's dispatcher rules alike (its `_stalled`). Without it, on Solomon's C1 sets (windows
  opening minutes in, 25 s services, a 10 s timeout) every robot counted every other one out,
  each became its own SSI auctioneer and awarded itself everything.
* **Reports.** A `Progress` at every change and every `report_period` (what the supervisor's
  busy/idle view and the teammates' stall watch read), and, every `report_period`, one `Queued`
  per task of its queue (monitoring only).
"""

from __future__ import annotations

import collections
import logging
import math
from types import MappingProxyType
from typing import ClassVar, Iterable, Mapping

from mrta_zenoh.clock import EPSILON
from mrta_zenoh.planning import Problem
from mrta_zenoh.timetext import at

from ..runtime.coordinator import Coordinator, Say
from .executor import Readings, RouteExecutor
from .messages import Progress

MOVED = 0.05  # m: a teammate whose reported pose moved this far made progress
# m: a teammate this close to its task is there (waiting or serving: not stalled). Not the
# layer's 0.3 m stop tolerance: a robot serving can be pushed off it (Solomon C102, CBBA: 0.64 m
# during a 25 s service, declared stalled at 0.5); the analysis counts a service within the
# layer's tolerance + 1 m
AT_TASK = 1.0


class Watch:
    """One teammate as its reports show it: the last time it made progress."""

    def __init__(self) -> None:
        self.state: tuple | None = None
        self.task = ""  # the task it reports it is on
        self.pose: tuple[float, float] | None = None
        self.progress_at: float | None = None
        self.moved_at: float | None = None  # when its pose last moved (not its first report)
        self.busy = False

    def heard(self, msg: Progress, at_: float) -> None:
        state = (msg.task, tuple(msg.served))
        moved = self.pose is None or math.dist(self.pose, (msg.x, msg.y)) > MOVED
        if moved and self.pose is not None:
            self.moved_at = at_
        if state != self.state or moved:
            self.state, self.pose = state, (msg.x, msg.y)
            self.progress_at = at_
        self.busy, self.task = bool(msg.task), msg.task


class RouteLogic(Coordinator):
    """A pure decision logic keeping this robot's own route (SSI's auction, CBBA's bundle), as
    `OwnRouteCoordinator` drives it: the Coordinator's hooks (what it hears, its teammates, its
    `tick` returning the runtime's `Say`) and two of its own, no-op by default like the others
    (py_trees' Behaviour): `route()`, the tasks in the order it would serve them, and
    `served(task, at)`, this robot finished one."""

    HOOKS: ClassVar[tuple[str, ...]] = Coordinator.HOOKS + ("route", "served")
    # teammate → why it is counted out while its token lives ("stalled"), as its coordinator
    # declared it (OwnRouteCoordinator, which gives the logic a dict of its own; none alone)
    declared: Mapping[str, str] = MappingProxyType({})
    # the instance it plans (SSI's, CBBA's): what a teammate's task is — where, its window, its
    # service (OwnRouteCoordinator's stall watch); None: a plain timeout
    problem: Problem | None = None

    def out(self) -> tuple[str, ...]:
        """Who this robot counts out while their token lives, and why (`robot:reason`), as its
        messages say it: what the summary's declared stretches are read from."""
        return tuple(f"{r}:{why}" for r, why in sorted(self.declared.items()))

    def route(self) -> list[str]:
        return []

    def served(self, task_id: str, at: float) -> None:
        pass


class OwnRouteCoordinator(Coordinator):
    """Subclasses set `logic_kinds` (what the logic hears) and implement `settled`."""

    logic_kinds: ClassVar[tuple[str, ...]] = ()
    log: ClassVar[logging.Logger] = logging.getLogger("mrta.agent")

    def __init__(self, robot_id: str, logic: RouteLogic, readings: Readings, report_period: float,
                 progress_timeout: float):
        self.robot_id = robot_id
        self.logic = logic
        self.readings = readings
        self.report_period, self.progress_timeout = report_period, progress_timeout
        self.route = RouteExecutor()
        self.tokens: dict[str, bool] = {}      # teammate → its token lives
        self.watch: dict[str, Watch] = {}      # teammate → its progress
        self.told: dict[str, bool] = {}        # teammate → alive, as last told to the logic
        self.declared: dict[str, str] = {}     # teammate → "stalled" (RouteLogic.declared)
        self.declared_at: dict[str, float] = {}  # … since when
        self.logic.declared = self.declared
        self._active: str | None = None
        self._reported: tuple | None = None
        self._report_at: float | None = None

    @property
    def listens(self) -> tuple[str, ...]:  # type: ignore[override]
        return self.logic_kinds + ("progress",)

    @property
    def active_task(self) -> str | None:
        return self._active

    def settled(self, now: float) -> bool:
        """Whether the logic's route is the one to serve now (module docstring)."""
        raise NotImplementedError

    # ------------------------------------------------------------------ teammates
    def teammate(self, robot: str, alive: bool) -> None:
        self.tokens[robot] = alive
        if alive:
            self.watch.pop(robot, None)  # a robot back starts with a clean record
        self._tell(robot)

    def _tell(self, robot: str, now: float | None = None) -> None:
        token = self.tokens.get(robot, False)
        stalled = token and now is not None and self._stalled(robot, now)
        alive = token and not stalled
        if self.told.get(robot) != alive:
            self.told[robot] = alive
            if stalled and now is not None:
                self.declared[robot], self.declared_at[robot] = "stalled", now
            else:
                self.declared.pop(robot, None)
                self.declared_at.pop(robot, None)
            self.logic.teammate(robot, alive)

    def _stalled(self, robot: str, now: float) -> bool:
        w = self.watch.get(robot)
        if w is None:
            return False
        since = self.declared_at.get(robot)
        if since is not None:  # declared: until it is seen to move (module docstring)
            return w.moved_at is None or w.moved_at <= since
        return (w.busy and w.progress_at is not None
                and now > self._progress_due(w) + EPSILON)

    def _progress_due(self, w: Watch) -> float:
        """When a busy teammate last seen progressing at `progress_at` is stalled (module
        docstring, "Waiting is not stalling")."""
        start, p = w.progress_at, self.logic.problem
        try:
            task = p.tasks[p.task_index(w.task)] if p is not None else None
        except KeyError:
            task = None  # not in this robot's instance (yet): a plain timeout
        if task is not None and w.pose is not None:
            if math.dist(w.pose, task.position) <= AT_TASK:
                start = max(start, task.opens) + task.service
            else:
                start = max(start, task.arrival)
        return start + self.progress_timeout

    def hear(self, kind: str, sender: str, message, at_: float) -> bool:
        if kind == "progress":
            if not isinstance(message, Progress) or sender == self.robot_id:
                return False
            self.watch.setdefault(sender, Watch()).heard(message, at_)
            return True
        if kind not in self.logic_kinds:
            return False
        return self.logic.hear(kind, sender, message, at_)

    # tasks at run time (Coordinator's hooks): the logic plans them; the executor serves them
    # through the plugins the driver grew
    def tasks_added(self, growth, now: float) -> None:
        self.logic.tasks_added(growth, now)

    def task_priority(self, task_id: str, priority: int, now: float) -> None:
        self.logic.task_priority(task_id, priority, now)

    def task_cancelled(self, task_id: str, now: float) -> None:
        self.logic.task_cancelled(task_id, now)

    def refusals(self):
        """What this adapter and its logic refused (`Coordinator.refuse`; the logic's
        `refused` counter: SSI's and CBBA's rules of what a message is believed for)."""
        return collections.Counter(super().refusals()) + self.logic.refused

    # ------------------------------------------------------------------ one tick
    def tick(self, now: float) -> Iterable[Say]:
        for robot in list(self.tokens):
            before = self.told.get(robot)
            self._tell(robot, now)
            if before and not self.told[robot]:
                self.log.warning("%s: %s made no progress for %g s: counted as gone %s",
                                 self.robot_id, robot, self.progress_timeout, at(now))
        out = list(self.logic.tick(now))
        changed = False
        if self.settled(now) and self.route.queue != self._wanted():
            for change in self.route.assign(self._wanted(), now):
                self.log.info("%s: left %s %s", self.robot_id, change.task, at(now))
            changed = True
        for change in self.route.step(now, self.readings):
            self.log.info("%s: %s %s %s", self.robot_id, change.kind.replace("_", " "),
                          change.task, at(now))
            if change.kind == "served":
                self.logic.served(change.task, change.at)
            changed = True
        self._active = self.route.active(now, self.readings)
        return out + self._report(now, changed)

    def _wanted(self) -> list[str]:
        """The logic's route, the task set off to first (module docstring)."""
        wanted = self.logic.route()
        current = self.route.current
        if current is not None and current in wanted:
            wanted = [current] + [t for t in wanted if t != current]
        return wanted

    def _report(self, now: float, changed: bool) -> list[Say]:
        r = self.route
        pose = self.readings.pose() or (0.0, 0.0, 0.0)
        state = (r.current or "", r.last or "", tuple(r.queue), tuple(r.served_ids()))
        due = self._report_at is None or now - self._report_at >= self.report_period - EPSILON
        if not (changed or due or state != self._reported):
            return []
        out = [r.progress(pose)]
        self._reported = state
        if due:
            self._report_at = now
            out += r.queued(lossy=True)
        return out
