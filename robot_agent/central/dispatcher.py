"""The dispatcher's decisions, as pure logic on an injected time (a `Coordinator`: the agent
runtime's fixed driver runs it in the dispatcher process, as it runs a robot's logic — the
inbox in (time, sender, key, sequence) order, sender checks, faults; docs/central.md).

What it does at each tick:

1. **Learns.** Tasks whose arrival time has come are known. Robots' reports (`Progress`) say
   what each served (in order), what it set off to, its queue, what it left for good (its
   evaluator said the task is done by a teammate, cancelled or expired: never planned again —
   a robot cut off by a partition may have delivered a task unseen, and the robot it is then
   granted to knows from its board; it used to stand by it, be declared stalled and be left
   out for good) and where it is; a robot's agent token says whether it lives.
2. **Watches progress.** A robot that has a task but has not progressed on it — moved, turned,
   changed task — for `progress_timeout` (beyond its task's window opening and service time
   once it is there, and not before the task's arrival) is *stalled*; one not heard for
   `progress_timeout` is *silent*; one whose token went has *crashed*. Each is out of the
   plan; a silent one comes back when it is heard again, a stalled one when it is seen to move
   again (a task served or changed does not count: a robot stripped of its queue changes task
   without moving).
3. **Re-plans** on an arrival, a completion, a loss or a return (planner.py: the residual
   problem on the model's clock, kept unless beaten), and records the decision (`Plan`).
4. **Sends queues**, each robot its own, when they change and every `resend_period`. A task is
   put in a robot's queue only once no other robot may still be serving it: every other robot's
   last report shows it neither set off to it nor queued, or that robot crashed, or it is silent
   (it stopped by its lease before the dispatcher gave up on it: docs/central.md, "No task
   served twice"). A queue is cut before its first task that cannot be granted yet, so a robot
   serves its plan's order and waits rather than skip ahead.

**What a report is believed for** (docs/security.md). A `Progress` speaks for its sender's own
queue only: a task counts as served, set off to or queued by a robot only if the dispatcher
granted it to that robot (sent it in a queue); a task served counts once, for the first robot
that reported it (a robot cut off by a partition may serve a task the dispatcher meanwhile
granted to another: both serve it, the second report is no completion), and only if that robot
could serve it (capability, capacity). What is not believed is refused and counted by sender
and reason (`Coordinator.refuse`), never raised: no report can stop the dispatcher. A report
acknowledging a queue version the dispatcher never sent shows that a robot applied a forged
queue: counted, and the dispatcher's versions continue above it (up to MAX_VERSION / 2), so its
next queue to that robot is newer and believed again.
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass, field
from typing import Iterable

from mrta_zenoh.clock import EPSILON
from mrta_zenoh.planning import Problem
from mrta_zenoh.planning.insertion import binding
from mrta_zenoh import refusal_tally, timetext
from mrta_zenoh.timetext import at

from ..runtime.coordinator import Coordinator, Say
from .messages import MAX_VERSION, Progress
from .params import DispatcherParams
from .planner import INSERTION, Outcome, Situation, ms, solve

log = logging.getLogger("mrta.central")

MOVED = 0.05     # m: a robot this far from where it last progressed has progressed
TURNED = 0.1     # rad: so has one that turned this much
AT_TASK = 0.5    # m: a robot this close to its task is serving it (the task's service counts)
HISTORY = 256    # decisions kept for inspection (tests, a debugger)

CRASHED, STALLED, SILENT = "crashed", "stalled", "silent"

# why a claim of a report was not believed (module docstring; Coordinator.refuse)
NOT_GRANTED = "not_granted"      # served, set off to or queued a task never granted to it
# served a task another robot reported served first (mrta_zenoh.refusal_tally: the summary
# reads it, a task served twice)
SERVED_TWICE = refusal_tally.SERVED_TWICE
IMPOSSIBLE = "impossible"        # served a task it cannot serve (capability, capacity)
UNKNOWN_TASK = "unknown_task"    # named a task the instance does not have (refused whole)
VERSION_NOT_SENT = "version_not_sent"  # applied a queue version the dispatcher never sent


@dataclass
class RobotView:
    """What the dispatcher knows of one robot."""

    alive: bool = False
    joined: float | None = None             # when its token came (its silence counts from it)
    lost: str | None = None                 # CRASHED, STALLED, SILENT; None: in the plan
    report: Progress | None = None
    heard: float | None = None              # when its last report counts as heard
    progressed: float | None = None         # when it last progressed
    where: tuple[float, float, float] | None = None  # its pose then
    served: list[str] = field(default_factory=list)  # what it served, as believed, in order
    claimed: set[str] = field(default_factory=set)   # what its reports said it served
    granted: set[str] = field(default_factory=set)   # every task ever sent it in a queue
    withdrew: set[str] = field(default_factory=set)  # what its reports said it left for good

    @property
    def on(self) -> str:
        """The task its last report has it set off to, if granted to it ("" none)."""
        report = self.report
        return report.task if report is not None and report.task and \
            report.task in self.granted else ""

    def holds(self, task: str) -> bool:
        """Whether its last report has `task` set off to or queued (a granted one only)."""
        report = self.report
        return report is not None and task in self.granted and \
            (report.task == task or task in report.queue)


@dataclass
class Sent:
    """The queue last sent to a robot, and every queue sent that it has not acknowledged yet
    (a report with that version or a later one): a robot may still apply those."""

    version: int
    tasks: tuple[str, ...]
    at: float
    unacked: list[tuple[int, tuple[str, ...]]] = field(default_factory=list)


@dataclass
class Decision:
    at: float
    version: int
    trigger: str
    outcome: Outcome


@dataclass
class Dispatcher(Coordinator):
    """One dispatcher (module docstring). `problem` is the instance (every robot and task, in
    its order); `name` its process name (what its keys and robots know it by)."""

    problem: Problem
    params: DispatcherParams
    name: str = "dispatcher"
    robots: dict[str, RobotView] = field(default_factory=dict)
    known: set[str] = field(default_factory=set)
    done: dict[str, str] = field(default_factory=dict)          # task → who served it
    # never planned again: under hard windows, due passed; a task a robot left for good
    closed: set[str] = field(default_factory=set)
    plan: dict[str, list[str]] = field(default_factory=dict)    # robot → route after commitment
    sent: dict[str, Sent] = field(default_factory=dict)
    version: int = 0
    decisions: list[Decision] = field(default_factory=list)
    start: float | None = None
    _triggers: list[str] = field(default_factory=list)
    _resend: set[str] = field(default_factory=set)  # robots owed a queue under a new version
    # task → its priority, for tasks given one at run time (0 otherwise): each robot's planned
    # route serves its higher-priority tasks first (`_replan`)
    priority: dict[str, int] = field(default_factory=dict)

    listens = ("progress",)

    def __post_init__(self) -> None:
        self.robots = {r.id: RobotView() for r in self.problem.robots}
        self._task = {t.id: t for t in self.problem.tasks}

    # ------------------------------------------------------------ what it hears
    def teammate(self, robot: str, alive: bool) -> None:
        view = self.robots.get(robot)
        if view is None:
            return  # not a robot of the instance
        view.alive = alive
        if alive:
            view.joined = None  # set at the next tick (the driver tells at a tick's start)
            # its silence counts from its return, not from its last report before it went (a
            # robot back from a real network cut was declared silent at once)
            view.heard = None
            if view.lost == CRASHED:
                view.lost = None
                self._triggers.append("return")
        elif view.lost != STALLED:
            view.lost = CRASHED
            self._triggers.append("loss")

    def hear(self, kind: str, sender: str, message, at: float) -> bool:
        view = self.robots.get(sender)
        if view is None or not isinstance(message, Progress):
            return False
        if any(t not in self._task for t in (*message.queue, *message.served,
                                              *message.withdrawn)) \
                or (message.task and message.task not in self._task):
            self.refuse("progress", sender, UNKNOWN_TASK)
            return False  # names a task the instance does not have: refused whole
        if message.version > self.version:
            self.refuse("progress", sender, VERSION_NOT_SENT)
            if message.version <= MAX_VERSION // 2:
                self.version = message.version
                self._resend.add(sender)
        before = view.report
        view.report, view.heard = message, at
        sent = self.sent.get(sender)
        if sent is not None:
            sent.unacked = [(v, q) for v, q in sent.unacked if v > message.version]
        if message.task and message.task not in view.granted \
                and (before is None or message.task != before.task):
            self.refuse("progress", sender, NOT_GRANTED)
        planned = self.plan.get(sender, [])
        on = view.on
        if on and (before is None or on != before.task) \
                and on not in self.done and planned[:1] != [on]:
            self._triggers.append("deviation")  # it set off to another task than planned
        if view.lost == SILENT:
            view.lost = None
            self._triggers.append("return")
        pose = (message.x, message.y, message.theta)
        moved = _moved(view.where, pose)
        if view.lost == STALLED and before is not None and moved:
            view.lost = None  # seen to move again: back in the plan
            log.warning("%s: %s moves again %s: back in the plan", self.name, sender, timetext.at(at))
            self._triggers.append("return")
        if before is None or message.task != before.task or message.served != before.served \
                or moved:
            view.progressed, view.where = at, pose
        for task in message.served:
            self._served(sender, view, task)
        for task in message.withdrawn:
            self._withdrawn(sender, view, task, at)
        return True

    def _withdrawn(self, rid: str, view: RobotView, task: str, at: float) -> None:
        """Robot `rid` left `task` for good, its evaluator said (done by a teammate — one cut
        off from the dispatcher may have delivered it unseen —, cancelled, expired): never
        planned again, believed for a task granted to it only (what it may say of its own
        queue; a served claim has the same reach)."""
        if task in view.withdrew:
            return
        view.withdrew.add(task)
        if task not in view.granted:
            self.refuse("progress", rid, NOT_GRANTED)
        elif task not in self.done and task not in self.closed:
            self.closed.add(task)
            log.warning("%s: %s left %s for good (its evaluator: done by a teammate, cancelled or "
                        "expired) %s: not planned again", self.name, rid, task, timetext.at(at))
            self._triggers.append("completion")

    def _served(self, rid: str, view: RobotView, task: str) -> None:
        """Robot `rid` reports `task` served: believed once, if it may (module docstring)."""
        if task in view.claimed:
            return
        view.claimed.add(task)
        i, j = self.problem.robot_index(rid), self.problem.task_index(task)
        cap = self.problem.robots[i].capacity
        if task not in view.granted:
            self.refuse("progress", rid, NOT_GRANTED)
        elif task in self.done:
            self.refuse("progress", rid, SERVED_TWICE, forged=False)  # a partition does it
            log.warning("%s: %s reports %s served, which %s served first: counted once",
                        self.name, rid, task, self.done[task])
        elif not self.problem.capable(i, j) or (cap is not None and len(view.served) >= cap):
            self.refuse("progress", rid, IMPOSSIBLE)
        else:
            self.done[task] = rid
            view.served.append(task)
            self._triggers.append("completion")

    # ------------------------------------------------------------ tasks at run time
    def tasks_added(self, growth, now: float) -> None:
        """Tasks submitted at run time (runtime/growth.py): the problem grows by them (their
        indices after the instance's), and each is learnt as an arrival — at this tick, since
        it arrived at the instant it entered — so the plan is solved again with it."""
        self.problem = growth.problem(self.problem)
        self._task = {t.id: t for t in self.problem.tasks}
        self.priority.update({t.id: t.priority for t in growth.tasks if t.priority})

    def task_priority(self, task_id: str, priority: int, now: float) -> None:
        """A new priority: the plan is solved again, its routes ordered by it (`_replan`)."""
        if task_id in self._task and self.priority.get(task_id, 0) != priority:
            self.priority[task_id] = priority
            self._triggers.append("reprioritization")

    def task_cancelled(self, task_id: str, now: float) -> None:
        """A task cancelled at run time is never planned again (its holder leaves it on its
        own: route.executor), and the plan is solved again without it."""
        if task_id in self._task and task_id not in self.done and task_id not in self.closed:
            self.closed.add(task_id)
            self._triggers.append("cancellation")

    # ------------------------------------------------------------ one decision step
    def tick(self, now: float) -> Iterable[Say]:
        if self.start is None:
            self.start = now
            self._triggers.append("start")
        for view in self.robots.values():
            if view.alive and view.joined is None:
                view.joined = now
        for task in self.problem.tasks:
            if task.id not in self.known and task.arrival <= now + EPSILON:
                self.known.add(task.id)
                self._triggers.append("arrival")
            if binding(self.problem) and task.due < now - EPSILON:
                self.closed.add(task.id)  # missed (planner.py, "Time windows")
        self._watch(now)
        out: list[Say] = []
        if self._triggers:
            trigger = _first(self._triggers)
            self._triggers.clear()
            out.append(self._replan(now, trigger))
        out += self._queues(now)
        return out

    def _watch(self, now: float) -> None:
        timeout = self.params.progress_timeout
        for rid, view in self.robots.items():
            if not view.alive or view.lost is not None:
                continue
            last = view.heard if view.heard is not None else view.joined
            if last is not None and now - last > timeout + EPSILON:
                view.lost = SILENT
            elif self._stalled(view, now):
                view.lost = STALLED
            else:
                continue
            log.warning("%s: %s is %s %s: re-planning its tasks", self.name, rid, view.lost,
                        at(now))
            self._triggers.append("loss")

    def _stalled(self, view: RobotView, now: float) -> bool:
        report = view.report
        if report is None or not report.task or report.task in self.done \
                or view.progressed is None:
            return False
        task = self._task[report.task]
        # at its task it may wait for the window to open, then serves (issue 49)
        if math.hypot(report.x - task.position[0], report.y - task.position[1]) <= AT_TASK:
            start = max(view.progressed, task.opens) + task.service
        else:
            start = max(view.progressed, task.arrival)
        return now > start + self.params.progress_timeout + EPSILON

    # ------------------------------------------------------------ planning
    def available(self) -> list[str]:
        return [r.id for r in self.problem.robots
                if self.robots[r.id].alive and self.robots[r.id].lost is None]

    def commitment(self, rid: str) -> tuple[str, ...]:
        """What robot `rid` served, in order, then the task it set off to (if it is still in
        the plan and the task is not done)."""
        view = self.robots[rid]
        served = tuple(view.served)
        on = view.on
        cap = self.problem.robots[self.problem.robot_index(rid)].capacity
        if view.lost is None and on and on not in self.done \
                and (cap is None or len(served) < cap):
            return served + (on,)
        return served

    def commitments(self) -> dict[str, tuple[str, ...]]:
        """Every robot's commitment, a task set off to by two available robots kept by one:
        a robot cut off (silent) and re-planned out comes back still reporting the task it
        was on, which the dispatcher meanwhile granted to another. The robot it was granted to
        last keeps it (the latest queue sent holding it; else the first in the instance's
        order); the other's queue then leaves it out, and no third robot is granted it until
        that one has let it go (`grantable`)."""
        out = {r.id: self.commitment(r.id) for r in self.problem.robots}
        order = {r.id: k for k, r in enumerate(self.problem.robots)}
        on: dict[str, list[str]] = {}
        for rid in self.available():
            if out[rid] and out[rid][-1] not in self.done:
                on.setdefault(out[rid][-1], []).append(rid)
        for task, rids in on.items():
            if len(rids) > 1:
                keeper = min(rids, key=lambda r: (-self._granted_at(r, task), order[r]))
                for rid in rids:
                    if rid != keeper:
                        out[rid] = out[rid][:-1]
        return out

    def _granted_at(self, rid: str, task: str) -> float:
        sent = self.sent.get(rid)
        return sent.at if sent is not None and task in sent.tasks else -math.inf

    def situation(self) -> Situation:
        available = self.available()
        commitments = self.commitments()
        committed = {c[-1] for r in available if (c := commitments[r]) and c[-1] not in
                     self.done}
        open_tasks = tuple(t.id for t in self.problem.tasks if t.id in self.known
                           and t.id not in self.done and t.id not in committed
                           and t.id not in self.closed)
        return Situation(commitments, tuple(available), open_tasks)

    def _replan(self, now: float, trigger: str) -> Say:
        p = self.params
        situation = self.situation()
        outcome = solve(self.problem, situation, p.objective, exact_limit=p.exact_limit,
                        solutions=p.solutions, time_limit=p.time_limit,
                        search_limit=p.search_limit,
                        current=self.plan if self.decisions else None)
        self.plan = self.by_priority(outcome.routes)
        self.version += 1
        self.decisions.append(Decision(now, self.version, trigger, outcome))
        del self.decisions[:-HISTORY]
        if outcome.unassigned:
            log.info("%s: nobody available may serve %s %s", self.name,
                     ", ".join(outcome.unassigned), at(now))
        routes = tuple(f"{rid}:{','.join(self.wanted(rid))}" for rid in situation.available)
        return Say("plan", dict(version=self.version, trigger=trigger,
                                objective=p.objective.value, value=outcome.value,
                                method=outcome.method, solve_ms=ms(outcome.seconds),
                                routes=routes, capped=self.capped(situation, outcome),
                                out=tuple(f"{rid}:{view.lost}" for rid, view in
                                          self.robots.items() if view.lost is not None)))

    def by_priority(self, routes: dict[str, list[str]]) -> dict[str, list[str]]:
        """Each robot's route with its higher-priority tasks first, in the planner's order
        otherwise (a stable sort; all priority 0 — every instance's own task — leaves the
        plan as solved). Not in the planner's objective, which has no priorities: who serves a
        task is the plan's, when it comes in that robot's queue is the priority's (docs/tasks.md)."""
        if not self.priority:
            return routes
        return {rid: sorted(route, key=lambda t: -self.priority.get(t, 0))
                for rid, route in routes.items()}

    def capped(self, situation: Situation, outcome: Outcome) -> bool:
        """Whether the decision's search was stopped by its cap, or found nothing within it
        (then the plan is by insertion): its plan then depends on the machine (issue 51.2).
        The search's own account (planning.routing.BestFound.capped: the CPU seconds of the
        search, looked at each solution, or OR-Tools' wall-clock last resort), not the
        decision's wall time: on a loaded machine a search of 50 open tasks among 50 robots —
        2.7 CPU-s — took 18.5 s of wall time, and the study's 50-robot central runs were all
        called inexact for searches nothing had cut short (issue 48). A plan by insertion
        alone (more open tasks than `search_limit`) ran no search and is never capped."""
        return outcome.capped

    # ------------------------------------------------------------ queues
    def wanted(self, rid: str) -> list[str]:
        """The queue the plan gives robot `rid`: the task it is on, then its route."""
        if rid not in self.available():
            return []
        commitment = self.commitments()[rid]
        task = self.robots[rid].on
        on = [commitment[-1]] if task and commitment and commitment[-1] == task else []
        return on + [t for t in self.plan.get(rid, ())
                     if t not in self.done and t not in self.closed and t not in on]

    def grantable(self, rid: str, task: str) -> bool:
        """Whether no robot but `rid` may still be serving `task`: none reports it, and none
        was sent a queue holding it that it has not acknowledged since (module docstring) —
        or `rid` is on it already and keeps it (`commitments`: back from a partition, another
        robot may still report it; withholding it would only make `rid` leave it too)."""
        if self.robots[rid].on == task and self.commitments()[rid][-1:] == (task,):
            return True
        for other, view in self.robots.items():
            if other == rid or not view.alive or view.lost == SILENT:
                continue  # crashed; or cut off, and stopped by its lease
            if view.holds(task):
                return False
            sent = self.sent.get(other)
            if sent is not None and any(task in q for _, q in sent.unacked):
                return False
        return True

    def queue_for(self, rid: str) -> tuple[str, ...]:
        out = []
        for task in self.wanted(rid):
            if not self.grantable(rid, task):
                break
            out.append(task)
        return tuple(out)

    def _queues(self, now: float) -> list[Say]:
        out = []
        for r in self.problem.robots:
            view = self.robots[r.id]
            if not view.alive:
                continue
            tasks = self.queue_for(r.id)
            sent = self.sent.get(r.id)
            stale = r.id in self._resend
            self._resend.discard(r.id)
            if sent is not None and sent.tasks == tasks and not stale \
                    and now - sent.at < self.params.resend_period - EPSILON:
                continue
            if sent is None or sent.tasks != tasks or stale:
                self.version += 1
                unacked = [] if sent is None else sent.unacked
                sent = self.sent[r.id] = Sent(self.version, tasks, now,
                                              unacked + [(self.version, tasks)])
                view.granted.update(tasks)
            else:
                sent.at = now
            out.append(Say("queue", dict(robot=r.id, version=sent.version, tasks=tasks), r.id))
        return out


def _moved(before: tuple[float, float, float] | None, now: tuple[float, float, float]) -> bool:
    if before is None:
        return True
    turn = math.atan2(math.sin(now[2] - before[2]), math.cos(now[2] - before[2]))
    return math.hypot(now[0] - before[0], now[1] - before[1]) >= MOVED or abs(turn) >= TURNED


ORDER = ("start", "loss", "return", "arrival", "cancellation", "reprioritization", "completion",
         "deviation")


def _first(triggers: list[str]) -> str:
    """The trigger a decision is recorded under when several came at once."""
    return min(triggers, key=ORDER.index)
