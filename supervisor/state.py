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

What the bus cannot be trusted with (docs/architecture.md):
* every id is checked (one key chunk, ≤ 64 characters) before it reaches any state;
* where a monitor's key expression starts with a wildcard (`*/alliance/…`), the first chunk of a
  sample's key is the publishing robot: a sample whose robot field names another robot is
  dropped and counted (`key_mismatch`) — robot1 cannot make robot2 look busy;
* robots and tasks that are not in the application never join the picture: they raise an
  `unknown_robot` / `unknown_task` alarm, kept for at most MAX_UNKNOWN ids (the rest counted
  as `unknown_overflow`) and cleared `unknown_expiry` seconds after the id was last seen (or
  after its last liveliness token went), so a flood of invented ids costs bounded memory. The
  robot is recognised before anything else is read: a sample on `robot9/…` from a robot
  outside the application raises `unknown_robot` whatever its fields hold, and so does a
  liveliness token under `robot9/**` (a robot outside the team holding an agent token);
* every name that reaches an alarm, a log line or a table goes through
  mrta_zenoh.untrusted.visible (control characters shown as `\x1b`); a sample key whose first
  chunk is no id is counted (`bad_keys`);
* the ROS 2 graph (mrta_zenoh.ros2.graph) is bounded and linear; a token that does not parse
  raises `ros2_invalid_token`, a full graph `ros2_graph_full`, while they last;
* a robot is driven through ROS 2 while a bridge holds `@mrta/ros2_bridge/<robot>`: from the
  first ROS 2 node seen in its namespace on, it is online only while such a node lives
  (`driver_lost` otherwise). The rule goes with the bridge: a node declared in the namespace
  of a robot nobody bridges (a forgery, a stray tool) changes nothing, and when the bridge
  goes its `driver_lost` goes with it. A robot so driven whose bridge goes while its driver
  lives is offline with `bridge_lost` (its agent's commands reach nothing) until a bridge
  comes back or its ROS 2 nodes go too;
* while the simulation clock is stopped (`clock_stopped` alarm) robots are shown `unknown`:
  their held states are stale, not busy;
* a lockstep simulator's report of participants it no longer waits for raises
  `participant_unresponsive` (mrta_zenoh.lockstep).
"""

from __future__ import annotations

import logging
import operator
import threading
from dataclasses import dataclass, field
from typing import Any, Callable

from mrta_zenoh import keys
from mrta_zenoh.fieldpath import FieldPath, FieldPathError
from mrta_zenoh.messages import GenericMessage
from mrta_zenoh.ros2.graph import Ros2Graph
from mrta_zenoh.untrusted import visible
from mrta_zenoh.toolchain.model import Application, Architecture, Topic

from .holders import History, SampleHolder, StateChange

log = logging.getLogger("mrta.supervisor")

ROLES = ("busy_robots", "idle_robots", "incoming_tasks", "allocated_tasks")


@dataclass
class Monitor:
    role: str
    topic: Topic
    key_expr: str
    path: FieldPath

    @property
    def by_sender(self) -> bool:
        """`*/…` or `**/…`: one key per robot, whose first chunk is the publishing robot."""
        return self.key_expr.split("/", 1)[0] in ("*", "**")


def group_reader(monitors: list[Monitor]):
    """One attrgetter reading every monitor's field at once, for a group of monitors of one
    type whose paths are all names; None otherwise (the full path resolves them one by one)."""
    paths = [m.path.steps for m in monitors]
    if len({m.topic.type for m in monitors}) != 1 or \
            not all(p and all(type(x) is str for x in p) for p in paths):
        return None
    r = operator.attrgetter(*(".".join(p) for p in paths))
    if len(paths) == 1:
        return lambda msg: (r(msg),)  # the same shape as the multi-field getter
    return r


def monitors_of(arch: Architecture) -> list[Monitor]:
    out = []
    for role in ROLES:
        t = getattr(arch, role)
        if t is not None:
            out.append(Monitor(role, t, t.key_expr, FieldPath.parse(t.field)))
    return out


@dataclass
class RobotInfo:
    id: str
    known: bool                 # part of the application
    busy: SampleHolder
    idle: SampleHolder
    tokens: set[str] = field(default_factory=set)
    ever_token: bool = False
    bridges: set[str] = field(default_factory=set)  # `@mrta/ros2_bridge/<id>` tokens alive
    ros2_driver: bool = False   # a ROS 2 node lives in the robot's namespace
    ever_ros2: bool = False     # … and one did since a bridge took the robot
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
    MAX_UNKNOWN = 100  # unknown robot / task ids remembered (and alarmed) at once
    MAX_STRANGER_TOKENS = 16  # live tokens remembered per robot outside the application
    MAX_NAME = 100  # characters of a name from the network shown in an alarm or a log line

    def __init__(self, arch: Architecture, app: Application, now: float = 0.0,
                 unattended_after: float = 30.0, duplicate_after: float = 5.0,
                 quiet: bool = False, unknown_expiry: float = 30.0, ros2_domain: int = 0):
        self.arch, self.app = arch, app
        self.ros2 = Ros2Graph(ros2_domain)
        self.monitors = monitors_of(arch)
        self._timeouts = {m.role: m.topic.timeout for m in self.monitors}
        self.unattended_after = unattended_after
        self.duplicate_after = duplicate_after
        self.unknown_expiry = unknown_expiry
        self.history = History()
        self.alarms: dict[tuple[str, str], float] = {}
        self.counts = {"samples": 0, "wrong_type": 0, "field_errors": 0, "key_mismatch": 0,
                       "unknown": 0, "unknown_overflow": 0, "bad_keys": 0,
                       "stranger_tokens": 0}
        self._stranger_tokens: dict[str, set[str]] = {}  # unknown robot → its live tokens
        self._warned: set[tuple[str, str]] = set()
        self._lock = threading.Lock()
        self.robots: dict[str, RobotInfo] = {}
        self.tasks: dict[str, TaskInfo] = {}
        self.allocations: dict[tuple[str, str], SampleHolder] = {}
        self.unknown: dict[tuple[str, str], float] = {}  # (kind, id) → last seen
        self.clock_stopped = False
        self.started = now
        self._log = log if not quiet else logging.getLogger("mrta.supervisor.replay")
        if quiet:
            self._log.setLevel(logging.ERROR)  # a replay re-lives old alarms; do not re-announce
        self._dup_since: dict[str, float] = {}
        self._lockstep_dropped = 0  # the simulator's refused StepDones, as last reported
        self._robot_alloc: dict[str, set[str]] = {}  # robot → tasks whose holder is high
        self._task_alloc: dict[str, set[str]] = {}   # task → robots whose holder is high
        self._ids: dict[str, str | None] = {}        # raw id text → normalised id (None: invalid)
        self._fast: dict[str, tuple] = {}            # key → (type, field values, holders) last accepted
        self._ingest: dict[int, tuple] = {}          # id(monitor group) → (group, ingest)
        for r in app.robots:
            rid = keys.normalize_robot_id(r.id)
            self.robots[rid] = RobotInfo(rid, True, SampleHolder(self._timeouts.get("busy_robots", 1.0)),
                                         SampleHolder(self._timeouts.get("idle_robots", 1.0)),
                                         state="offline", since=now)
        for t in app.tasks():
            self.tasks[t] = TaskInfo(t, True, SampleHolder(self._timeouts.get("incoming_tasks", 1.0)),
                                     since=now)

    # -------------------------------------------------------------------------------- inputs

    def _id(self, raw: str) -> str | None:
        """A valid id (robot ids lose a leading `/`), or None; memoised, as ids repeat."""
        out = self._ids.get(raw, False)
        if out is False:
            rid = raw.strip().strip("/")
            out = rid if keys.is_id(rid) else None
            if len(self._ids) >= 10_000:
                self._ids.clear()
            self._ids[raw] = out
        return out

    def _unknown(self, kind: str, ident: str, now: float) -> None:
        self.counts["unknown"] += 1
        k = (kind, ident)
        if k not in self.unknown and len(self.unknown) >= self.MAX_UNKNOWN:
            self.counts["unknown_overflow"] += 1
            return
        self.unknown[k] = now
        self._raise(f"unknown_{kind}", ident, now)

    def on_sample(self, monitors: list[Monitor], key: str, type_name: str, message: Any,
                  now: float) -> None:
        """A sample for the monitors reading its key expression (one subscription serves them)."""
        self._ingest_fn(monitors)(key, type_name, message, lambda: now)

    def handler_for(self, monitors: list[Monitor], now: Callable[[], float]):
        """The bus handler for one group of monitors: `handler(sample)`, timed by `now()`."""
        ingest = self._ingest_fn(monitors)

        def handler(sample) -> None:
            ingest(sample.key, sample.type_name, sample.message, now)

        return handler

    def _ingest_fn(self, monitors: list[Monitor]):
        """`ingest(key, type_name, message, now)` for one group of monitors.

        The hot path: a sample that says again what the last accepted sample on its key said
        (same type, same field values) while every state it holds is still high only moves
        those holders' deadlines — one C-level read of all fields, a dict lookup, a comparison.
        Anything else (a new value, a state that fell, a robot that went offline, a bad sample)
        takes the full path, which is also what fills the cache."""
        cached = self._ingest.get(id(monitors))
        if cached is not None and cached[0] is monitors:  # the group is kept: its id stays its own
            return cached[1]
        read = group_reader(monitors)
        fast, lock, counts, full = self._fast, self._lock, self.counts, self._on_sample

        def ingest(key: str, type_name: str, message: Any, now: Callable[[], float]) -> None:
            vals = None
            if read is not None and type(message) is not GenericMessage:
                try:
                    vals = read(message)
                except AttributeError:
                    pass
            t = now()
            with lock:
                if vals is not None:
                    hit = fast.get(key)
                    if hit is not None and hit[0] == type_name and hit[1] == vals:
                        for h in hit[2]:
                            if not h.high:
                                break
                            h.last, h.until = t, t + h.timeout
                        else:
                            counts["samples"] += 1
                            return
                full(monitors, key, type_name, message, t, vals)

        self._ingest[id(monitors)] = (monitors, ingest)
        return ingest

    def _on_sample(self, monitors: list[Monitor], key: str, type_name: str, message: Any,
                   now: float, vals) -> None:
        self.counts["samples"] += 1
        if monitors[0].by_sender:  # who sent it comes first: a stranger is a stranger
            sender_id = self._id(keys.first_chunk(key))
            if sender_id is None:
                self.counts["bad_keys"] += 1
                return
            if sender_id not in self.robots:
                self._unknown("robot", sender_id, now)
                return
        values: dict[str, str] = {}
        for m in monitors:
            if type_name != m.topic.type:
                self.counts["wrong_type"] += 1
                shown = visible(type_name, self.MAX_NAME)
                if (m.key_expr, shown) not in self._warned and len(self._warned) < 1000:
                    self._warned.add((m.key_expr, shown))
                    self._log.warning("%s: ignoring samples of type %s (the architecture says %s)",
                                      m.key_expr, shown, m.topic.type)
                return
            try:
                value = m.path.get(message)
            except FieldPathError:
                self.counts["field_errors"] += 1
                return
            if type(value) is not str:
                if not isinstance(value, (int, float)) or isinstance(value, bool):
                    self.counts["field_errors"] += 1
                    return
                value = str(value)
            ident = self._id(value)
            if ident is None:  # not an id: a sample is used whole or not at all
                self.counts["field_errors"] += 1
                return
            values[m.role] = ident
        sender = keys.first_chunk(key)
        robot = values.get("busy_robots") or values.get("idle_robots")
        if robot is not None and monitors[0].by_sender and robot != sender:
            self.counts["key_mismatch"] += 1
            return
        held: list[SampleHolder] = []
        for role in ("busy_robots", "idle_robots"):
            rid = values.get(role)
            if rid is not None:
                r = self.robots.get(rid)
                if r is None:
                    self._unknown("robot", rid, now)
                    return
                h = r.busy if role == "busy_robots" else r.idle
                held.append(h)
                if h.sample(now):  # only rising edges change a state
                    self._reassess_robot(r, now)
        tid = values.get("incoming_tasks")
        if tid is not None:
            t = self.tasks.get(tid)
            if t is None:
                self._unknown("task", tid, now)
                return
            held.append(t.incoming)
            if t.incoming.sample(now):
                self._reassess_task(t, now)
        tid = values.get("allocated_tasks")
        if tid is not None:
            rid = robot or self._id(sender)
            if rid is None or rid not in self.robots:
                if rid is not None:
                    self._unknown("robot", rid, now)
                return
            if tid not in self.tasks:
                self._unknown("task", tid, now)
                return
            holder = self.allocations.get((tid, rid))
            if holder is None:
                holder = SampleHolder(self._timeouts["allocated_tasks"])
                self.allocations[(tid, rid)] = holder
            held.append(holder)
            if holder.sample(now, tid):
                self._robot_alloc.setdefault(rid, set()).add(tid)
                self._task_alloc.setdefault(tid, set()).add(rid)
                self._reassess_robot(self.robots[rid], now)
                self._reassess_task(self.tasks[tid], now)
        if vals is not None and held:
            if len(self._fast) >= 10_000:  # keys come from the network: bounded
                self._fast.clear()
            self._fast[key] = (type_name, vals, tuple(held))

    def on_clock(self, stopped: bool, now: float) -> None:
        """The simulation clock stopped (or came back): robots are `unknown` meanwhile."""
        with self._lock:
            if stopped == self.clock_stopped:
                return
            self.clock_stopped = stopped
            if stopped:
                self._raise("clock_stopped", "clock", now)
            else:
                self._clear("clock_stopped", "clock", now)
            for r in self.robots.values():
                self._reassess_robot(r, now)

    def on_lockstep(self, unresponsive: tuple[str, ...], now: float,
                    rivals: tuple[str, ...] = (), dropped: int = 0) -> None:
        """The lockstep simulator's report (mrta_zenoh.lockstep.LockstepStatus): participants
        it stopped waiting for (`participant_unresponsive`), other clock sources or lockstep
        runs on the bus (`clock_rival`: one source per run, so a second is a misconfiguration
        or a forgery), and StepDones it refused (`lockstep_refused`, raised while the count
        grows from one report to the next)."""
        with self._lock:
            for kind, subjects in (("participant_unresponsive", unresponsive),
                                   ("clock_rival", rivals)):
                names = {visible(n, self.MAX_NAME) for n in subjects[:self.MAX_UNKNOWN]}
                for k, subject in list(self.alarms):
                    if k == kind and subject not in names:
                        self._clear(k, subject, now)
                for name in sorted(names):
                    self._raise(kind, name, now)
            if dropped > self._lockstep_dropped:
                self._raise("lockstep_refused", "simulator", now)
            else:
                self._clear("lockstep_refused", "simulator", now)
            self._lockstep_dropped = max(self._lockstep_dropped, dropped)

    def restart(self, now: float) -> None:
        """Time restarted (a new simulation run): everything held belongs to the old run."""
        with self._lock:
            for r in self.robots.values():
                r.busy.drop()
                r.idle.drop()
            for (tid, rid), h in self.allocations.items():
                if h.drop():
                    self._unallocate(tid, rid)
            for t in self.tasks.values():
                t.incoming.drop()
                t.since = now
            self._dup_since.clear()
            for r in self.robots.values():
                self._reassess_robot(r, now)
            for t in self.tasks.values():
                self._reassess_task(t, now)

    def on_liveliness(self, key: str, alive: bool, now: float) -> None:
        with self._lock:
            r = self.robots.get(keys.first_chunk(key))
            if r is None:  # not a robot of this application (another team, a forgery)
                self._stranger_token(key, alive, now)
                return
            rid = r.id
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

    def _stranger_token(self, key: str, alive: bool, now: float) -> None:
        """A token under `<id>/**` of a robot outside the application: `unknown_robot` while
        it lives (and `unknown_expiry` after), like a sample from it. Bounded: MAX_UNKNOWN
        robots (through `_unknown`), MAX_STRANGER_TOKENS keys each."""
        chunk = keys.first_chunk(key)
        rid = self._id(chunk)
        if rid is None:  # not even an id: shown escaped, counted
            self.counts["bad_keys"] += 1
            rid = visible(chunk, self.MAX_NAME)
        held = self._stranger_tokens.get(rid)
        if not alive:
            if held is not None:
                held.discard(key)
                if not held:
                    del self._stranger_tokens[rid]
            return
        self.counts["stranger_tokens"] += 1
        self._unknown("robot", rid, now)
        if ("robot", rid) not in self.unknown:  # over MAX_UNKNOWN: counted only
            return
        if held is None:
            held = self._stranger_tokens[rid] = set()
        if len(held) < self.MAX_STRANGER_TOKENS:
            held.add(key)

    def on_ros2_token(self, key: str, alive: bool, now: float) -> None:
        """A token of the ROS 2 graph (`@ros2_lv/<domain>/…`): the graph takes it in O(1)
        (mrta_zenoh.ros2.graph: bounded, never fatal), then only the robot whose nodes changed
        is looked at again."""
        change = self.ros2.on_token(key, alive)
        with self._lock:
            g = self.ros2
            for kind, bad in (("ros2_invalid_token", g.invalid_live > 0),
                              ("ros2_graph_full", g.refused_live > 0)):
                if bad:
                    self._raise(kind, g.key_expr, now)
                else:
                    self._clear(kind, g.key_expr, now)
            r = self.robots.get(change.robot) if change.robot is not None else None
            if r is not None:
                self._ros2_reassess(r, now)

    def on_bridge_token(self, key: str, alive: bool, now: float) -> None:
        """`@mrta/ros2_bridge/<robot>`: a bridge drives that robot through ROS 2 (or stopped)."""
        with self._lock:
            r = self.robots.get(key.rsplit("/", 1)[-1])
            if r is None:  # a robot outside the application: nothing of ours to drive
                return
            (r.bridges.add if alive else r.bridges.discard)(key)
            self._ros2_reassess(r, now)

    def _ros2_reassess(self, r: RobotInfo, now: float) -> None:
        r.ros2_driver = self.ros2.has_nodes(r.id)
        if not r.bridges:  # nobody bridges it: ROS 2 nodes in its namespace say nothing…
            self._clear("driver_lost", r.id, now)
            if r.ever_ros2 and r.ros2_driver:  # …unless a bridge drove them and died
                self._raise("bridge_lost", r.id, now)
            else:
                r.ever_ros2 = False
                self._clear("bridge_lost", r.id, now)
        else:
            self._clear("bridge_lost", r.id, now)
            r.ever_ros2 = r.ever_ros2 or r.ros2_driver
            if r.ever_ros2 and not r.ros2_driver:
                self._raise("driver_lost", r.id, now)
            else:
                self._clear("driver_lost", r.id, now)
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
            for (kind, ident), seen in list(self.unknown.items()):
                if kind == "robot" and ident in self._stranger_tokens:
                    self.unknown[(kind, ident)] = now  # its token still lives
                elif now - seen >= self.unknown_expiry:
                    del self.unknown[(kind, ident)]
                    self._clear(f"unknown_{kind}", ident, now)

    # ----------------------------------------------------------------------------- derivation

    def _online(self, r: RobotInfo) -> bool:
        if r.ever_ros2 and not (r.ros2_driver and r.bridges):
            return False
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
        if not r.known or (self.clock_stopped and online):
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
        if not t.known or self.clock_stopped:
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
        """`subject` is shown as given: an id checked by keys.is_id, or a name made visible
        where it came in (on_lockstep, _stranger_token)."""
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
                    "ros2": self.ros2.snapshot(),
                    "transitions": [t.to_json() for t in self.history.recent(transitions)],
                    "counts": dict(self.counts)}
