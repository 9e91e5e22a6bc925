"""What the supervisor knows: robots Idle / Busy / Offline, tasks and allocations, alarms.

Everything comes from the architecture file's monitors (monitors.py: what each role's field
means), so nothing here knows ALLIANCE: another architecture with other keys, fields and types
works unchanged. Samples are checked before they change anything (intake.py); ids outside the
application are reported, never shown as robots or tasks (strangers.py); alarms and the
lockstep simulator's reports: alarms.py.

* Offline comes from liveliness: a robot is online while any token under `<robot_id>/**` exists.
  A robot that never declared a token (an architecture without liveliness) counts as online
  while any of its monitors is high. A robot driven through ROS 2 is also offline when its
  driver or its bridge is gone (drivers.py).
* A task the application says is done, or not due yet (its mission hook's TaskWatch,
  tasks.py), is `done` / `waiting` and raises no `task_unattended` alarm.
* Tasks submitted at run time (mrta_zenoh.tasks, issue 50) are learnt from the intake's
  `tasks/change` (believed from the intake only, as the robots believe it: `header/frame_id`
  `tasks`): a submitted task is shown, held and alarmed like the application's own, and a
  cancelled one is `cancelled` (it needs no robot). Without it a robot's queue naming a
  submitted task raised `unknown_task`. A new run forgets them.
* A process of the run that is neither robot nor observer (central's dispatcher) is shown by
  its token (`@mrta/node/<name>`): online while it lives, `process_lost` when it goes while the
  run is on.
* On simulation time, while the clock is stopped (`clock_stopped`) robots are `unknown`: their
  held states are stale, not busy. Once the run has ended (its clock source's token is gone:
  the simulator exited) the picture stays as the run left it, with no alarm — its processes
  stopping then is no fault either. A new run (a restarted simulator) starts the picture
  afresh, as a supervisor started at that moment would see it, keeping only what still holds:
  the liveliness tokens and the ROS 2 graph.
"""
from __future__ import annotations

import logging
import threading
from typing import Any, Callable

from mrta_zenoh import keys
from mrta_zenoh.ros2.graph import Ros2Graph
from mrta_zenoh.tasks.intake import Limits
from mrta_zenoh.tasks.messages import INTAKE, Change, Op
from mrta_zenoh.toolchain.model import ApplicationFile, ArchitectureFile

from .alarms import Alarms, LockstepAlarms
from .drivers import Ros2Drivers
from .entities import Allocations, RobotInfo, Serving, TaskInfo
from .holders import History, SampleHolder, StateChange
from .intake import Ids, Intake
from .monitors import Monitor, monitors_of
from .strangers import MAX_NAME, MAX_STRANGER_TOKENS, MAX_UNKNOWN, Strangers
from .tasks import TaskStatus, TaskWatch, waits_for_a_robot

log = logging.getLogger("mrta.supervisor")
SETTLED = ("done", "cancelled")  # a task in either state needs nothing more
MAX_SUBMITTED = Limits.tasks  # tasks submitted at run time the picture takes (the intake's bound)


class Supervisor:
    MAX_UNKNOWN = MAX_UNKNOWN
    MAX_STRANGER_TOKENS = MAX_STRANGER_TOKENS
    MAX_NAME = MAX_NAME

    def __init__(self, arch: ArchitectureFile, app: ApplicationFile, now: float = 0.0,
                 unattended_after: float = 30.0, duplicate_after: float = 5.0,
                 quiet: bool = False, unknown_expiry: float = 30.0, ros2_domain: int = 0,
                 watch: TaskWatch | None = None, serving: Serving | None = None):
        self.arch, self.app, self.watch, self.serving = arch, app, watch, serving
        # whether the simulation run's clock source is gone (set by api.Refresh on simulated
        # time: SimClock.ended); a robot's token lost then is the run ending, not a fault
        self.source_gone: Callable[[], bool] = lambda: False
        self.monitors = monitors_of(arch)
        self._timeouts = {m.role: m.topic.timeout for m in self.monitors}
        self.unattended_after = unattended_after
        self.duplicate_after = duplicate_after
        self.unknown_expiry = unknown_expiry
        self.started = now
        self.counts = {"samples": 0, "wrong_type": 0, "field_errors": 0, "key_mismatch": 0,
                       "unknown": 0, "unknown_overflow": 0, "bad_keys": 0,
                       "stranger_tokens": 0, "task_news": 0, "task_news_ignored": 0,
                       "task_changes": 0, "task_changes_ignored": 0}
        self._lock = threading.Lock()
        self.history = History()
        self._alarms = Alarms(self.history, quiet)
        self.drivers = Ros2Drivers(Ros2Graph(ros2_domain), self._alarms)
        self.robots: dict[str, RobotInfo] = {}
        self.tasks: dict[str, TaskInfo] = {}
        self.submitted: set[str] = set()  # tasks that entered at run time (on_change)
        self.processes: dict[str, dict] = {}  # name → {"online", "since"} (MAX_UNKNOWN at most)
        ids = Ids()
        self.strangers = Strangers(self._alarms, self.counts, unknown_expiry, ids)
        self.intake = Intake(ids, self.robots, self.counts, self.strangers, self._apply,
                             self._lock, log if not quiet else logging.getLogger(
                                 "mrta.supervisor.replay"))
        self._fresh(now)
        for r in app.robots:
            rid = r.id
            self.robots[rid] = self._robot(rid, now)
        for t in app.tasks():
            self.tasks[t] = self._task(t, now)
        self._schedule(now)

    def _fresh(self, now: float) -> None:
        """What a run starts without: allocations, the clock's and lockstep's word."""
        self.held = Allocations(self._timeouts.get("allocated_tasks", 1.0))
        self.clock_stopped = False
        self.run_ended = False
        self._dup_since: dict[str, float] = {}
        self.lockstep = LockstepAlarms(self._alarms, MAX_UNKNOWN, MAX_NAME)
        if self.serving is not None:
            self.serving.clear()

    def _robot(self, rid: str, now: float) -> RobotInfo:
        return RobotInfo(rid, True, SampleHolder(self._timeouts.get("busy_robots", 1.0)),
                         SampleHolder(self._timeouts.get("idle_robots", 1.0)),
                         state="offline", since=now)

    def _task(self, tid: str, now: float) -> TaskInfo:
        return TaskInfo(tid, True, SampleHolder(self._timeouts.get("incoming_tasks", 1.0)),
                        since=now)

    def _schedule(self, now: float) -> None:
        self._scheduled_at = now
        for status in self.watch.schedule() if self.watch is not None else ():
            self._task_status(status, now)

    def _lapsed(self, now: float) -> set[str]:
        """The watch's word on what time alone settled (TaskWatch.lapsed), for tasks neither
        done nor held: the tasks it changed."""
        changed = set()
        for status in self.watch.lapsed(now - self._scheduled_at) if self.watch else ():
            t = self.tasks.get(status.task)
            if t is None or t.status in SETTLED or self.held.robots_on(t.id):
                continue
            if t.status != status.state:
                t.status, t.until = status.state, None
                changed.add(t.id)
        return changed

    # ------------------------------------------------------------------ the parts' state
    @property
    def ros2(self) -> Ros2Graph:
        return self.drivers.graph

    @ros2.setter
    def ros2(self, graph: Ros2Graph) -> None:
        self.drivers.graph = graph

    @property
    def alarms(self) -> dict[tuple[str, str], float]:
        return self._alarms.up

    @property
    def allocations(self) -> dict[tuple[str, str], SampleHolder]:
        return self.held.holders

    @property
    def unknown(self) -> dict[tuple[str, str], float]:
        return self.strangers.seen

    @property
    def _stranger_tokens(self) -> dict[str, set[str]]:
        return self.strangers.tokens

    @property
    def _ids(self) -> dict[str, str | None]:
        return self.intake.ids.memo

    # -------------------------------------------------------------------------------- inputs
    def on_sample(self, monitors: list[Monitor], key: str, type_name: str, message: Any,
                  now: float) -> None:
        """A sample for the monitors reading its key expression (one subscription serves them)."""
        self.intake.ingest_fn(monitors)(key, type_name, message, lambda: now)

    def handler_for(self, monitors: list[Monitor], now: Callable[[], float]):
        """The bus handler for one group of monitors: `handler(sample)`, timed by `now()`."""
        ingest = self.intake.ingest_fn(monitors)

        def handler(sample) -> None:
            ingest(sample.key, sample.type_name, sample.message, now)

        return handler

    def _apply(self, values: dict[str, str], key: str, now: float) -> list[SampleHolder] | None:
        """A checked reading (role → id; intake.py) into the picture; the holders it keeps high."""
        held: list[SampleHolder] = []
        robot = values.get("busy_robots") or values.get("idle_robots")
        for role in ("busy_robots", "idle_robots"):
            rid = values.get(role)
            if rid is not None:
                r = self.robots.get(rid)
                if r is None:
                    self.strangers.heard("robot", rid, now)
                    return None
                h = r.busy if role == "busy_robots" else r.idle
                held.append(h)
                if h.sample(now):  # only rising edges change a state
                    self._reassess_robot(r, now)
        tid = values.get("incoming_tasks")
        if tid is not None:
            t = self.tasks.get(tid)
            if t is None:
                self.strangers.heard("task", tid, now)
                return None
            held.append(t.incoming)
            if t.incoming.sample(now):
                self._reassess_task(t, now)
        tid = values.get("allocated_tasks")
        if tid is not None:
            holder = self._allocation(tid, robot or self.intake.ids(keys.first_chunk(key)), now)
            if holder is None:
                return None
            held.append(holder)
        return held

    def _allocation(self, tid: str, rid: str | None, now: float) -> SampleHolder | None:
        if rid is None or rid not in self.robots:
            if rid is not None:
                self.strangers.heard("robot", rid, now)
            return None
        if tid not in self.tasks:
            self.strangers.heard("task", tid, now)
            return None
        holder, rose = self.held.sample(tid, rid, now)
        if rose:
            self._reassess_robot(self.robots[rid], now)
            self._reassess_task(self.tasks[tid], now)
        return holder

    def on_doing_sample(self, key: str, message: Any, now: float) -> None:
        """A sample of the architecture's own reports of who serves what (Serving)."""
        with self._lock:
            if self.serving is not None:
                self.serving.read(key, message, now)

    def _task_shown(self, rid: str, now: float) -> tuple[str | None, list[str]]:
        """The task a robot serves now and the tasks it holds: for a robot with a queue, the
        one its architecture's own latest report says it is on (Serving), and the queue; else
        the one task the monitors say it holds (an architecture without queues — ALLIANCE,
        MURDOCH — holds one, and its monitors are what the view has always shown)."""
        held = self.held.tasks_of(rid)
        doing = self.serving.of(rid, now) if self.serving is not None else None
        if doing is not None and doing.queue is not None:
            return (doing.task if doing.active else None), list(doing.queue)
        return (held[0] if held else None), held

    def on_task_sample(self, key: str, message: Any, now: float) -> None:
        """A sample of the application's TaskWatch feed (tasks.py)."""
        status = self.watch.read(key, message) if self.watch is not None else None
        with self._lock:
            if status is None:
                self.counts["task_news_ignored"] += 1
                return
            self._task_status(status, now)

    def on_change(self, message: Any, now: float) -> None:
        """A sample of the intake's `tasks/change` (module docstring): a submitted task joins
        the picture, a cancelled one needs no robot. Not from the intake, not an id, or past
        the intake's own bound of tasks a run takes: counted, ignored."""
        with self._lock:
            tid = self.intake.ids(message.task_id) if isinstance(message, Change) else None
            if tid is None or message.header.frame_id != INTAKE \
                    or (tid not in self.tasks and len(self.submitted) >= MAX_SUBMITTED):
                self.counts["task_changes_ignored"] += 1
                return
            self.counts["task_changes"] += 1
            if message.op == Op.SUBMIT and tid not in self.tasks:
                self.tasks[tid] = self._task(tid, now)
                self.submitted.add(tid)
                self.strangers.forget("task", tid, now)  # heard before its change came
            t = self.tasks.get(tid)
            if t is not None and message.op == Op.CANCEL and t.status not in SETTLED:
                t.status, t.until = "cancelled", None
            if t is not None:
                self._reassess_task(t, now)

    def _task_status(self, status: TaskStatus, now: float) -> None:
        t = self.tasks.get(status.task)
        if t is None:  # the application speaks of a task its robots do not have
            self.counts["task_news_ignored"] += 1
            return
        self.counts["task_news"] += 1
        t.status = status.state
        t.until = None if status.seconds is None else now + status.seconds
        self._reassess_task(t, now)

    def all_done(self) -> bool:
        """Whether nothing is left to serve: the application said every task is done for good
        (its TaskWatch: a delivered task; not patrol's report, done only until its next
        period) or missed (a hard window passed, TaskWatch.lapsed): the mission runner then
        ends the run."""
        with self._lock:
            tasks = [t for t in self.tasks.values() if t.known]
            return bool(tasks) and all(t.status in (*SETTLED, "missed") and t.until is None
                                       for t in tasks)

    def on_clock(self, stopped: bool, now: float, ended: bool = False) -> None:
        """The simulation clock stopped (or came back): robots are `unknown` meanwhile. A run
        that `ended` (its source is gone) raises nothing: the picture stays as it left it."""
        with self._lock:
            self._clock(stopped and not ended, ended, now)

    def _clock(self, stopped: bool, ended: bool, now: float) -> None:
        if (stopped, ended) == (self.clock_stopped, self.run_ended):
            return
        self.clock_stopped, self.run_ended = stopped, ended
        self._alarms.set("clock_stopped", "clock", stopped, now)
        if ended:
            self.history.add(StateChange(now, "run", "clock", "running", "ended"))
        for r in self.robots.values():
            self._reassess_robot(r, now)

    def on_lockstep(self, unresponsive: tuple[str, ...], now: float,
                    rivals: tuple[str, ...] = (), dropped: int = 0) -> None:
        """The lockstep simulator's report (alarms.LockstepAlarms)."""
        with self._lock:
            self.lockstep.report(unresponsive, rivals, dropped, now)

    def restart(self, now: float) -> None:
        """Time restarted (a new simulation run): start afresh, as a supervisor started now
        would — what the old run held, its alarms and its transitions belong to it. What
        still holds is kept: the liveliness tokens, the ROS 2 graph and its bridges, the ids
        outside the application still remembered."""
        with self._lock:
            self.history.clear()
            self.history.add(StateChange(now, "run", "clock", "", "restarted"))
            self._alarms.up.clear()
            self._fresh(now)
            self.intake.forget()
            for rid, old in list(self.robots.items()):
                r = self.robots[rid] = self._robot(rid, now)
                r.tokens, r.bridges = old.tokens, old.bridges
                r.ros2_driver, r.ever_ros2 = old.ros2_driver, old.ever_ros2
                r.ever_token = bool(r.tokens)  # a robot lost in the old run is just offline
                self.drivers.reassess(r, now)
                self._reassess_robot(r, now)
            for tid in self.submitted:  # the old run's
                del self.tasks[tid]
            self.submitted.clear()
            for tid in self.tasks:
                self.tasks[tid] = self._task(tid, now)
            self._schedule(now)
            for t in self.tasks.values():
                self._reassess_task(t, now)
            self.strangers.restart(now)
            self.drivers.graph_alarms(now)

    def on_liveliness(self, key: str, alive: bool, now: float) -> None:
        with self._lock:
            r = self.robots.get(keys.first_chunk(key))
            if r is None:  # not a robot of this application (another team, a forgery)
                self.strangers.token(key, alive, now)
                return
            if alive:
                r.tokens.add(key)
                r.ever_token = True
            else:
                if not self.run_ended and self.source_gone():
                    # the run's processes stop as it ends, its clock source first: seen now,
                    # not at the next refresh, so that their going raises no alarm
                    self._clock(False, True, now)
                r.tokens.discard(key)
                if self.run_ended:
                    # the run is over and its processes stop: the picture stays as the run left
                    # it (issue 51: at a replay's end every robot turned offline as if dead)
                    return
                if not r.tokens:
                    # its messages can no longer be trusted to keep arriving: drop held states now
                    r.busy.drop()
                    r.idle.drop()
                    for tid in self.held.drop_robot(r.id):
                        self._reassess_task(self.tasks[tid], now)
            self._reassess_robot(r, now)

    def on_process_token(self, key: str, alive: bool, now: float) -> None:
        """`@mrta/node/<name>`: a process of the run that is neither robot nor observer."""
        name = self.intake.ids(key.rsplit("/", 1)[-1])
        with self._lock:
            if name is None or (name not in self.processes
                                and len(self.processes) >= MAX_UNKNOWN):
                self.counts["bad_keys"] += 1
                return
            if not alive and self.run_ended:  # over: stopping is no news (on_liveliness)
                return
            if self.processes.get(name, {}).get("online") != alive:
                self.history.add(StateChange(now, "process", name,
                                             "online" if not alive else "offline",
                                             "online" if alive else "offline"))
                self.processes[name] = {"online": alive, "since": now}
            if alive:
                self._alarms.clear("process_lost", name, now)
            elif not self.run_ended and not self.source_gone():
                self._alarms.raise_("process_lost", name, now)

    def on_ros2_token(self, key: str, alive: bool, now: float) -> None:
        """A token of the ROS 2 graph (`@ros2_lv/<domain>/…`): the graph takes it in O(1),
        then only the robot whose nodes changed is looked at again (drivers.py)."""
        changed = self.drivers.on_token(key, alive, now)
        with self._lock:
            self.drivers.graph_alarms(now)
            r = self.robots.get(changed) if changed is not None else None
            if r is not None:
                self.drivers.reassess(r, now)
                self._reassess_robot(r, now)

    def on_bridge_token(self, key: str, alive: bool, now: float) -> None:
        """`@mrta/ros2_bridge/<robot>`: a bridge drives that robot through ROS 2 (or stopped)."""
        with self._lock:
            r = self.robots.get(key.rsplit("/", 1)[-1])
            if r is None:  # a robot outside the application: nothing of ours to drive
                return
            self.drivers.on_bridge(r, key, alive)
            self.drivers.reassess(r, now)
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
                    self._alarms.raise_("messages_stopped", r.id, now)
            for tid, robot in self.held.update(now):
                changed_tasks.add(tid)
                changed_robots.add(robot)
            for t in self.tasks.values():
                if t.incoming.update(now):
                    changed_tasks.add(t.id)
                if t.until is not None and now >= t.until:  # due again (or arrived)
                    t.status, t.until = None, None
                    changed_tasks.add(t.id)
            changed_tasks |= self._lapsed(now)
            for rid in changed_robots:
                self._reassess_robot(self.robots[rid], now)
            for tid in changed_tasks:
                self._reassess_task(self.tasks[tid], now)
            for t in self.tasks.values():
                self._task_alarms(t, now)
            self.strangers.expire(now)

    # ----------------------------------------------------------------------------- derivation
    def _online(self, r: RobotInfo) -> bool:
        if self.drivers.cut_off(r):
            return False
        if r.tokens:
            return True
        if r.ever_token:
            return False
        return r.busy.high or r.idle.high or self.held.tasks_of(r.id) != []

    def _reassess_robot(self, r: RobotInfo, now: float) -> None:
        online = self._online(r)
        if self.run_ended and not online:
            return  # its processes stopped after the run: as the run left it (on_liveliness)
        if not r.known or (self.clock_stopped and online):
            state = "unknown"
        elif not online:
            state = "offline"
        elif r.busy.high or self.held.tasks_of(r.id):
            state = "busy"
        else:
            state = "idle"
        if state != r.state:
            self.history.add(StateChange(now, "robot", r.id, r.state, state))
            r.state, r.since = state, now
        if r.known and r.ever_token:
            if r.tokens:
                self._alarms.clear("communication_lost", r.id, now)
            elif not self.run_ended:  # after the end of a run its processes stop: no fault
                self._alarms.raise_("communication_lost", r.id, now)
        if r.busy.high:
            self._alarms.clear("messages_stopped", r.id, now)

    def _reassess_task(self, t: TaskInfo, now: float) -> None:
        robots = self.held.robots_on(t.id)
        state = ("allocated" if robots else t.status if t.status is not None
                 else "incoming" if t.incoming.high else "unallocated")
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
        if not t.known or self.clock_stopped or self.run_ended:
            return
        waiting = not t.robots and t.status is None and self.watch is not None \
            and self.watch.served_in_turn and waits_for_a_robot(
                self.watch.servers(t.id), {r.id: r.state for r in self.robots.values()})
        if waiting:
            t.waited = now
        since = max(t.since, t.waited)
        if t.robots or t.status is not None or waiting:
            self._alarms.clear("task_unattended", t.id, now)
        elif now - since >= self.unattended_after:
            self._alarms.raise_("task_unattended", t.id, now, since=since)
        if self.arch.tasks_type == "SR" and len(t.robots) >= 2:
            first = self._dup_since.setdefault(t.id, now)
            if now - first >= self.duplicate_after:
                self._alarms.raise_("task_duplicated", t.id, now, since=first)
        else:
            self._dup_since.pop(t.id, None)
            self._alarms.clear("task_duplicated", t.id, now)

    # -------------------------------------------------------------------------------- output
    def snapshot(self, now: float, transitions: int = 20) -> dict:
        """The snapshot of docs/architecture.md: robots, tasks, alarms (+ recent transitions and counters)."""
        with self._lock:
            robots = []
            order = {rid: i for i, rid in enumerate(self.robots)}  # application order first
            for r in sorted(self.robots.values(), key=lambda r: (not r.known, order[r.id])):
                task, queue = self._task_shown(r.id, now)
                robots.append({"id": r.id, "state": r.state, "task": task, "queue": queue,
                               "online": self._online(r), "since": r.since})
            tasks = [{"id": t.id, "state": t.state, "robots": list(t.robots), "since": t.since}
                     for t in self.tasks.values()]
            processes = [{"id": name, **p} for name, p in sorted(self.processes.items())]
            return {"time": now, "application": self.app.name, "architecture": self.arch.name,
                    "robots": robots, "tasks": tasks, "processes": processes,
                    "alarms": self._alarms.to_json(),
                    "run_ended": self.run_ended, "ros2": self.ros2.snapshot(),
                    "transitions": [t.to_json() for t in self.history.recent(transitions)],
                    "counts": dict(self.counts)}
