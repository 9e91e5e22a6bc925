"""What the supervisor knows: robots Idle / Busy / Offline, tasks and allocations, alarms.

Everything comes from the architecture file's monitors (key expression, type, field path,
timeout), so nothing here knows ALLIANCE: another architecture with other keys, fields and types
works unchanged. The rules:

* `busy_robots` / `idle_robots`: the field's value is a robot id; it holds that state for `timeout`.
* `incoming_tasks`: the field's value is a task id waiting for a robot.
* `allocated_tasks`: the field's value is a task id; its robot is the `busy_robots` value of the
  same sample when both monitors read the same key expression (ALLIANCE's broadcast carries both),
  otherwise the first chunk of the sample's key (`robot1/…`).
* Offline comes from liveliness: a robot is online while any token under `<robot_id>/**` exists.
  A robot that never declared a token (an architecture without liveliness) counts as online
  while any of its monitors is high.
* Architecture names in the ROS form (`/alliance/x`) become `**/alliance/x`.
"""

from __future__ import annotations

import logging
import threading
from dataclasses import dataclass, field
from typing import Any

from mrta_zenoh import keys
from mrta_zenoh.fieldpath import FieldPath, FieldPathError
from mrta_zenoh.toolchain.model import Application, Architecture, Topic

from .holders import History, SampleHolder, StateChange

log = logging.getLogger("mrta.supervisor")

ROLES = ("busy_robots", "idle_robots", "incoming_tasks", "allocated_tasks")


def key_expr_for(topic_name: str) -> str:
    name = topic_name.strip()
    if name.startswith("/"):
        return "**/" + name.strip("/")
    return keys.validate_key_expr(name)


@dataclass
class Monitor:
    role: str
    topic: Topic
    key_expr: str
    path: FieldPath


def monitors_of(arch: Architecture) -> list[Monitor]:
    out = []
    for role in ROLES:
        t = getattr(arch, role)
        if t is not None:
            out.append(Monitor(role, t, key_expr_for(t.name), FieldPath.parse(t.field)))
    return out


@dataclass
class RobotInfo:
    id: str
    known: bool                 # part of the application
    busy: SampleHolder
    idle: SampleHolder
    tokens: set[str] = field(default_factory=set)
    ever_token: bool = False
    state: str = "offline"
    since: float = 0.0


@dataclass
class TaskInfo:
    id: str
    known: bool
    incoming: SampleHolder
    state: str = "unallocated"
    robots: tuple[str, ...] = ()
    since: float = 0.0


class Supervisor:
    def __init__(self, arch: Architecture, app: Application, now: float = 0.0,
                 unattended_after: float = 30.0, duplicate_after: float = 5.0,
                 quiet: bool = False):
        self.arch, self.app = arch, app
        self.monitors = monitors_of(arch)
        self._timeouts = {m.role: m.topic.timeout for m in self.monitors}
        self.unattended_after = unattended_after
        self.duplicate_after = duplicate_after
        self.history = History()
        self.alarms: dict[tuple[str, str], float] = {}
        self.counts = {"samples": 0, "wrong_type": 0, "field_errors": 0}
        self._warned: set[tuple[str, str]] = set()
        self._lock = threading.RLock()
        self.robots: dict[str, RobotInfo] = {}
        self.tasks: dict[str, TaskInfo] = {}
        self.allocations: dict[tuple[str, str], SampleHolder] = {}
        self.started = now
        self._log = log if not quiet else logging.getLogger("mrta.supervisor.replay")
        if quiet:
            self._log.setLevel(logging.ERROR)  # a replay re-lives old alarms; do not re-announce
        self._dup_since: dict[str, float] = {}
        self._robot_alloc: dict[str, set[str]] = {}  # robot → tasks whose holder is high
        self._task_alloc: dict[str, set[str]] = {}   # task → robots whose holder is high
        for r in app.robots:
            self._robot(keys.normalize_robot_id(r.id), now, known=True)
        for t in app.tasks():
            self._task(t, now, known=True)

    # ------------------------------------------------------------------------------ entities

    def _robot(self, rid: str, now: float, known: bool = False) -> RobotInfo:
        r = self.robots.get(rid)
        if r is None:
            r = RobotInfo(rid, known, SampleHolder(self._timeouts.get("busy_robots", 1.0)),
                          SampleHolder(self._timeouts.get("idle_robots", 1.0)),
                          state="offline" if known else "unknown", since=now)
            self.robots[rid] = r
            if not known:
                self.history.add(StateChange(now, "robot", rid, "", "unknown"))
        return r

    def _task(self, tid: str, now: float, known: bool = False) -> TaskInfo:
        t = self.tasks.get(tid)
        if t is None:
            t = TaskInfo(tid, known, SampleHolder(self._timeouts.get("incoming_tasks", 1.0)),
                         since=now)
            self.tasks[tid] = t
        return t

    # -------------------------------------------------------------------------------- inputs

    def on_sample(self, monitors: list[Monitor], key: str, type_name: str, message: Any,
                  now: float) -> None:
        """A sample for the monitors reading its key expression (one subscription serves them)."""
        with self._lock:
            self.counts["samples"] += 1
            values: dict[str, str] = {}
            for m in monitors:
                if type_name != m.topic.type:
                    self.counts["wrong_type"] += 1
                    if (m.key_expr, type_name) not in self._warned:
                        self._warned.add((m.key_expr, type_name))
                        self._log.warning("%s: ignoring samples of type %s (the architecture says %s)",
                                    m.key_expr, type_name, m.topic.type)
                    return
                try:
                    value = m.path.resolve(message)
                except FieldPathError:
                    self.counts["field_errors"] += 1
                    return
                if not isinstance(value, (str, int, float)) or isinstance(value, bool):
                    self.counts["field_errors"] += 1
                    return
                values[m.role] = str(value)
            try:  # a sample is used whole or not at all: one bad field drops it, counted once
                for role in ("busy_robots", "idle_robots"):
                    if role in values:
                        values[role] = keys.normalize_robot_id(values[role])
                if "allocated_tasks" in values:
                    values["@robot"] = keys.normalize_robot_id(
                        values.get("busy_robots") or keys.first_chunk(key))
            except keys.KeyExprError:
                self.counts["field_errors"] += 1
                return
            touched_robots: set[str] = set()
            touched_tasks: set[str] = set()
            for role, value in values.items():
                if role == "@robot":
                    continue
                # Only rising edges change a state; a sample that merely keeps a state high
                # costs a dict lookup and a timestamp (the supervisor's hot path).
                if role in ("busy_robots", "idle_robots"):
                    r = self._robot(value, now)
                    if (r.busy if role == "busy_robots" else r.idle).sample(now):
                        touched_robots.add(value)
                elif role == "incoming_tasks":
                    if self._task(value, now).incoming.sample(now):
                        touched_tasks.add(value)
                else:
                    robot = values["@robot"]
                    holder = self.allocations.get((value, robot))
                    if holder is None:
                        self._robot(robot, now)
                        self._task(value, now)
                        holder = SampleHolder(self._timeouts["allocated_tasks"])
                        self.allocations[(value, robot)] = holder
                    if holder.sample(now, value):
                        self._robot_alloc.setdefault(robot, set()).add(value)
                        self._task_alloc.setdefault(value, set()).add(robot)
                        touched_robots.add(robot)
                        touched_tasks.add(value)
            for rid in touched_robots:
                self._reassess_robot(self.robots[rid], now)
            for tid in touched_tasks:
                self._reassess_task(self.tasks[tid], now)

    def on_liveliness(self, key: str, alive: bool, now: float) -> None:
        with self._lock:
            try:
                rid = keys.normalize_robot_id(keys.first_chunk(key))
            except keys.KeyExprError:
                return
            if rid not in self.robots and not alive:
                return
            r = self._robot(rid, now)
            if alive:
                r.tokens.add(key)
                r.ever_token = True
            else:
                r.tokens.discard(key)
                if not r.tokens:
                    # its messages can no longer be trusted to keep arriving: drop held states now
                    r.busy.drop()
                    r.idle.drop()
                    for tid in list(self._robot_alloc.get(rid, ())):
                        self.allocations[(tid, rid)].drop()
                        self._unallocate(tid, rid)
                        self._reassess_task(self.tasks[tid], now)
            self._reassess_robot(r, now)

    def update(self, now: float) -> None:
        """Falling edges and time-based alarms; call a few times a second."""
        with self._lock:
            changed_robots: set[str] = set()
            changed_tasks: set[str] = set()
            for r in self.robots.values():
                fell_busy = r.busy.update(now)
                if r.idle.update(now) or fell_busy:
                    changed_robots.add(r.id)
                if fell_busy and not r.ever_token and r.known:
                    self._raise("messages_stopped", r.id, now)
            for (tid, robot), h in self.allocations.items():
                if h.update(now):
                    self._unallocate(tid, robot)
                    changed_tasks.add(tid)
                    changed_robots.add(robot)
            for t in self.tasks.values():
                if t.incoming.update(now):
                    changed_tasks.add(t.id)
            for rid in changed_robots:
                self._reassess_robot(self.robots[rid], now)
            for tid in changed_tasks:
                self._reassess_task(self.tasks[tid], now)
            for t in self.tasks.values():
                self._task_alarms(t, now)

    # ----------------------------------------------------------------------------- derivation

    def _online(self, r: RobotInfo) -> bool:
        if r.tokens:
            return True
        if r.ever_token:
            return False
        return r.busy.high or r.idle.high or self._robot_tasks(r.id) != []

    def _robot_tasks(self, rid: str) -> list[str]:
        return sorted(self._robot_alloc.get(rid, ()))

    def _unallocate(self, tid: str, rid: str) -> None:
        self._robot_alloc.get(rid, set()).discard(tid)
        self._task_alloc.get(tid, set()).discard(rid)

    def _reassess_robot(self, r: RobotInfo, now: float) -> None:
        online = self._online(r)
        if not r.known:
            state = "unknown"
        elif not online:
            state = "offline"
        elif r.busy.high or self._robot_tasks(r.id):
            state = "busy"
        else:
            state = "idle"
        if state != r.state:
            self.history.add(StateChange(now, "robot", r.id, r.state, state))
            r.state, r.since = state, now
        if r.known and r.ever_token:
            if not r.tokens:
                self._raise("communication_lost", r.id, now)
            else:
                self._clear("communication_lost", r.id, now)
        if r.busy.high:
            self._clear("messages_stopped", r.id, now)

    def _reassess_task(self, t: TaskInfo, now: float) -> None:
        robots = tuple(sorted(self._task_alloc.get(t.id, ())))
        state = "allocated" if robots else ("incoming" if t.incoming.high else "unallocated")
        if robots != t.robots:
            for robot in set(t.robots) - set(robots):
                self.history.add(StateChange(now, "allocation", f"{t.id}->{robot}", "allocated", ""))
            for robot in set(robots) - set(t.robots):
                self.history.add(StateChange(now, "allocation", f"{t.id}->{robot}", "", "allocated"))
            t.robots = robots
        if state != t.state:
            self.history.add(StateChange(now, "task", t.id, t.state, state))
            t.state, t.since = state, now
        self._task_alarms(t, now)

    def _task_alarms(self, t: TaskInfo, now: float) -> None:
        if not t.known:
            return
        if t.robots:
            self._clear("task_unattended", t.id, now)
        elif now - t.since >= self.unattended_after:
            self._raise("task_unattended", t.id, now, since=t.since)
        if self.arch.tasks_type == "SR" and len(t.robots) >= 2:
            first = self._dup_since.setdefault(t.id, now)
            if now - first >= self.duplicate_after:
                self._raise("task_duplicated", t.id, now, since=first)
        else:
            self._dup_since.pop(t.id, None)
            self._clear("task_duplicated", t.id, now)

    def _raise(self, kind: str, subject: str, now: float, since: float | None = None) -> None:
        if (kind, subject) not in self.alarms:
            self.alarms[(kind, subject)] = now if since is None else since
            self.history.add(StateChange(now, "alarm", f"{kind}:{subject}", "", "raised"))
            self._log.warning("alarm: %s %s", kind, subject)

    def _clear(self, kind: str, subject: str, now: float) -> None:
        if self.alarms.pop((kind, subject), None) is not None:
            self.history.add(StateChange(now, "alarm", f"{kind}:{subject}", "raised", "cleared"))

    # -------------------------------------------------------------------------------- output

    def snapshot(self, now: float, transitions: int = 20) -> dict:
        """The snapshot of docs/architecture.md: robots, tasks, alarms (+ recent transitions and counters)."""
        with self._lock:
            robots = []
            order = {rid: i for i, rid in enumerate(self.robots)}  # application order first
            for r in sorted(self.robots.values(), key=lambda r: (not r.known, order[r.id])):
                tasks = self._robot_tasks(r.id)
                robots.append({"id": r.id, "state": r.state, "task": tasks[0] if tasks else None,
                               "online": self._online(r), "since": r.since})
            tasks = [{"id": t.id, "state": t.state, "robots": list(t.robots), "since": t.since}
                     for t in self.tasks.values()]
            alarms = [{"kind": k, "subject": s, "since": since}
                      for (k, s), since in sorted(self.alarms.items(), key=lambda kv: kv[1])]
            return {"time": now, "application": self.app.name, "architecture": self.arch.name,
                    "robots": robots, "tasks": tasks, "alarms": alarms,
                    "transitions": [t.to_json() for t in self.history.recent(transitions)],
                    "counts": dict(self.counts)}
