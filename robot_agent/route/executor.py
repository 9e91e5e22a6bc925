"""What every route-executing architecture shares (central, SSI, CBBA): a robot holds an ordered
*route* of point tasks and serves them one after another, whoever decided the route — a
dispatcher's queue, the robot's own auction wins, its bundle.

* `RouteExecutor` — pure logic on an injected time: the route, the task the robot set off to
  (`current`, the one whose layers run), the tasks it served, in order and when. `assign`
  replaces the route (the decision logic's new plan), `step` moves on when the current task's
  layers say the robot finished it (`Layer.done`), `served` is what the decision logic needs to
  know (SSI's and CBBA's `served(task, at)`, central's progress report).
* `PluginReadings` — what the executor asks of the robot, answered from its plugins: whether a
  task's evaluator holds, whether its layers finished it, where the robot is.

Rules, each for a reason:

* The route is served in its order. A task at the head whose evaluator does not hold (its
  sensors are stale, it has not arrived) is *held*: the robot stands still and keeps the task
  rather than skip ahead, because the order is what the objective (planning.schedule) is
  computed along — a robot that skipped would serve another route than the one decided.
* A new route keeps the task the robot is on if it is in it (work in progress is not thrown
  away because a re-plan listed it later: it moves to the head) and abandons it otherwise —
  the robot stops (its layers are terminated) and the task is *left*, for whoever is given it.
* A served task is never served again: a route naming one is taken without it.
* A withdrawn task (its evaluator's `withdrawn`: cancelled at run time, expired, delivered
  by a teammate) is left at once and never set off to again, whatever route names it: held, it
  would keep the robot standing by a task nobody may serve (issue 50) — or one a teammate cut
  off from the dispatcher served unseen, and the dispatcher would take the robot for stalled
  (issue 51.2). Each report lists them (`Progress.withdrawn`), so whoever plans the route
  learns it.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import NamedTuple, Protocol, Sequence

from mrta_zenoh.messages import Odometry
from mrta_zenoh.paramdoc import Document, Duration, Id, Rate, Text, sized

from ..runtime.coordinator import Say
from ..runtime.params import (Doc, EvaluatorDoc, EvaluatorSpec, SensorParams, Sensors,
                              evaluator_spec, pose_topic_of)
from ..runtime.plugins import Plugins


class Readings(Protocol):
    """What the executor asks of the robot."""

    def applicable(self, task_id: str, now: float) -> bool: ...
    def done(self, task_id: str, now: float) -> bool: ...
    def pose(self) -> tuple[float, float, float] | None: ...
    def withdrawn(self, task_id: str, now: float) -> bool: ...


class PluginReadings:
    """`Readings` from a robot's plugins: a task's evaluator, its layers, a pose sensor."""

    def __init__(self, plugins: Plugins, pose_topic: str | None):
        self.plugins = plugins
        self.pose_topic = pose_topic

    def applicable(self, task_id: str, now: float) -> bool:
        ev = self.plugins.evaluators.get(task_id)
        return ev is not None and bool(ev.is_applicable(now))

    def done(self, task_id: str, now: float) -> bool:
        return any(layer.done(now) for layer in self.plugins.layers.get(task_id, ()))

    def withdrawn(self, task_id: str, now: float) -> bool:
        ev = self.plugins.evaluators.get(task_id)
        return ev is not None and bool(ev.withdrawn(now))

    def pose(self) -> tuple[float, float, float] | None:
        sensor = self.plugins.sensors.get(self.pose_topic) if self.pose_topic else None
        msg = sensor.latest if sensor is not None else None
        return (msg.pose.x, msg.pose.y, msg.pose.theta) if isinstance(msg, Odometry) else None


class Served(NamedTuple):
    task: str
    at: float  # when its service ended (the executor's clock)


class Change(NamedTuple):
    """What the executor did at a step, for the log and the reports: `set_off`, `served`,
    `left` (abandoned by a new route)."""

    kind: str
    task: str
    at: float


@dataclass
class RouteExecutor:
    """One robot's route (module docstring)."""

    route: list[str] = field(default_factory=list)   # still to serve, after `current`
    current: str | None = None                        # the task it set off to
    since: float | None = None                        # when it set off to `current`
    served: list[Served] = field(default_factory=list)
    last: str | None = None                           # the task it last served or left
    withdrawn: set[str] = field(default_factory=set)  # its evaluator said: never again

    def served_ids(self) -> list[str]:
        return [s.task for s in self.served]

    @property
    def queue(self) -> list[str]:
        """Its whole queue: the current task first, then the route."""
        return ([self.current] if self.current is not None else []) + self.route

    def assign(self, route: Sequence[str], now: float) -> list[Change]:
        """A new route (module docstring: the current task kept if in it, left otherwise)."""
        done = set(self.served_ids()) | self.withdrawn
        route = [t for t in dict.fromkeys(route) if t not in done]
        changes = []
        if self.current is not None:
            if self.current in route:
                route.remove(self.current)
            else:
                changes.append(Change("left", self.current, now))
                self.last, self.current, self.since = self.current, None, None
        self.route = route
        return changes

    def step(self, now: float, readings: Readings) -> list[Change]:
        """Move on: the current task served (its layers say so), then set off to the next."""
        changes = []
        for task in [t for t in self.queue if readings.withdrawn(t, now)]:
            self.withdrawn.add(task)
            if task == self.current:
                changes.append(Change("left", task, now))
                self.last, self.current, self.since = task, None, None
            else:
                self.route.remove(task)
        if self.current is not None and readings.done(self.current, now):
            self.served.append(Served(self.current, now))
            changes.append(Change("served", self.current, now))
            self.last, self.current, self.since = self.current, None, None
        if self.current is None and self.route:
            self.current, self.since = self.route.pop(0), now
            changes.append(Change("set_off", self.current, now))
        return changes

    def progress(self, pose: tuple[float, float, float], version: int = 0,
                 holding: bool = False) -> Say:
        """The `Progress` (route/messages.py) that reports this route from `pose`."""
        return Say("progress", dict(task=self.current or "", last=self.last or "",
                                    queue=tuple(self.queue), served=tuple(self.served_ids()),
                                    x=pose[0], y=pose[1], theta=pose[2], version=version,
                                    holding=holding, withdrawn=tuple(sorted(self.withdrawn))))

    def queued(self, lossy: bool) -> list[Say]:
        """One `Queued` per task of the queue, under the task's sub-key."""
        return [Say("queued", dict(task_id=task, place=place), task, lossy=lossy)
                for place, task in enumerate(self.queue)]

    def active(self, now: float, readings: Readings) -> str | None:
        """The task whose layers run now: the current one while its evaluator holds (held
        otherwise: module docstring)."""
        if self.current is not None and readings.applicable(self.current, now):
            return self.current
        return None

# A robot reports at least this often (s): its heartbeat to whoever plans its route, and how
# fresh the supervisor's view of it is.
REPORT_PERIOD = 1.0


class RouteTaskDoc(Doc):
    """One task a route-executing robot may serve, and the evaluator saying whether it can now."""

    task_id: Id
    evaluator: EvaluatorDoc


class RouteRobotFile(Doc, kw_only=True):
    """What central's and the own-route architectures' robot files share."""

    sensors: Sensors
    tasks: sized(RouteTaskDoc, "task")
    name: Text = ""
    spin_rate: Rate = 10.0
    control_rate: Rate = 10.0
    report_period: Duration = REPORT_PERIOD
    pose_topic: Text = ""  # none: the robot's pose is not read


def route_tasks(d: Document, f: RouteRobotFile, sensors: tuple[SensorParams, ...]
                ) -> tuple[tuple[EvaluatorSpec, ...], str | None]:
    """A route-executing robot's `tasks` (one evaluator per task it may serve, no task twice)
    and its `pose_topic` (one of its sensors)."""
    evaluators: list[EvaluatorSpec] = []
    for i, t in enumerate(f.tasks):
        if any(e.task_id == t.task_id for e in evaluators):
            raise d.error(("tasks", i, "task_id"), f"task {t.task_id!r} appears twice")
        evaluators.append(evaluator_spec(d, ("tasks", i, "evaluator"), t.task_id, t.evaluator,
                                         sensors))
    return tuple(evaluators), pose_topic_of(d, f.pose_topic or None, sensors)
