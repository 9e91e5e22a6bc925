"""The agent: one fixed driver for every architecture (composition, as py_trees composes
behaviours — an architecture is given to it, never subclassed from it).

The driver runs a single-threaded two-rate loop on the injected clock — the architecture's
decision step at its `spin_rate`, the active task's layers at `control_rate` — so the loop runs
identically in real time, at k× simulation speed, in lockstep and step by step in tests. It owns
what every architecture needs and none should write twice:

* the inbox: network callbacks only enqueue; the loop thread drains, so the decision logic is
  never touched by two threads;
* the team: robots whose agent of this architecture holds its liveliness token
  (`robotN/<namespace>/agent`); a message from anyone else is ignored and counted. A
  coordinator may also advertise subjects, one token each (`robotN/<namespace>/subject/<s>`),
  and hear its teammates' under the same rules (`Coordinator`). With a
  roster (`--team robot1,robot2,…`, set by launch files from the application's robots) only
  the robots on it can join: a token or a message from a robot outside it is ignored and
  counted (`ignored_outsiders`), so robots of another application — or forged ones claiming
  every task — cannot hold the team back. Without a roster (None) anyone holding a token
  joins: the open behaviour, right on a bus only the team uses (a secured fleet's ACL sees
  to that), wrong on one shared with strangers. What the tokens say is kept apart from the
  inbox (tokens.py, `TeamTokens`), so a flood of messages cannot push a teammate out;
* sender checks: a message's key names its sender, and its header must agree;
* what it refused: every sample the checks dropped and every claim the logic did not believe
  (`Coordinator.refuse`), by kind, sender and reason, said on `<name>/refused/tally`
  (mrta_zenoh/refusal_tally.py) when it changed — at most every TALLY_PERIOD, and as it
  stops — so that every summary shows it (a message from a teammate whose token has not come
  yet, or one the logic does not take without a reason — ALLIANCE's broadcast of a task this
  robot does not serve — is only counted here and logged: no evidence of anything);
* the instance: a message naming robots and tasks by index (messages.IndexedMessage: SSI's,
  CBBA's) goes out with the digest of the robot's instance (runtime.instance), and one from a
  teammate on another instance is ignored and counted (`ignored_other_instance`, and in what
  it refused: reason `other_instance`) with a warning naming both digests — read, it would be
  misread silently;
* publishing: every message the logic says goes out on `robotN/<namespace>/<kind>` with a header
  carrying the robot, the time and a per-key sequence number;
* the low level: plugins' set-up and shutdown, the active task's layers, a restart of time;
* the hooks of fault injection (faults.py, `FaultInjector`: crash, stall, partition, loss,
  latency, range, `@first`), called here because this is the one place every architecture's
  messages go out and come in, and its layers run.

An architecture supplies a `Coordinator` (its decision logic for one robot) through
`mrta_agent.runtime.architecture.AgentArchitecture`.
"""

from __future__ import annotations

import collections
import logging
import math
import threading
import time
from typing import TYPE_CHECKING, Callable, Iterable, Iterator

from mrta_zenoh.architectures import Architecture
from mrta_zenoh.bus import Bus, Sample
from mrta_zenoh.clock import EPSILON, Clock
from mrta_zenoh.errors import ConfigError
from mrta_zenoh.failure import FaultKind, FaultPlan, crash_now
from mrta_zenoh.keys import first_chunk
from mrta_zenoh.messages import Header, IndexedMessage
from mrta_zenoh.fault_tally import TALLY_PERIOD
from mrta_zenoh.refusal_tally import (MISMATCH, OFF_ROSTER, OTHER_INSTANCE, Refusals, refused_key,
                                      tally)
from mrta_zenoh.seeds import robot_rng
from mrta_zenoh.timetext import at
from mrta_zenoh.untrusted import visible

from .coordinator import Coordinator, Say
from .faults import FaultInjector
from .growth import RunTimeTasks
from .inbox import Heard, Inbox
from .plugins import AgentContext, Layer, Plugins
from .tokens import TeamTokens

if TYPE_CHECKING:
    import numpy as np  # annotations only: numpy loads when a plugin draws (mrta_zenoh.seeds)

log = logging.getLogger("mrta.agent")

TEAM_WAIT = 10.0  # wall s an agent in lockstep waits for its roster's tokens before its first tick
SUBJECT = "subject"  # subject tokens: robotN/<namespace>/subject/<subject> (never `…/agent`)
DROP_LOG_PERIOD = 10.0  # wall seconds between two log lines about the same kind of drop


class Agent:
    """One robot's agent: `architecture` says which keys and messages, `make_coordinator` builds
    the decision logic (again when time restarts), `plugins` are the robot's sensors, evaluators
    and layers."""

    stalled = False  # the stall fault struck: the layers no longer run
    withdrawn = False  # crashed in an agent host: its tokens and subscriptions are gone
    roster: frozenset[str] | None = None  # the only robots that may join the team (limit_team)

    def __init__(self, robot_id: str, architecture: Architecture,
                 make_coordinator: Callable[[], Coordinator], bus: Bus, clock: Clock,
                 rng: np.random.Generator | None, plugins: Plugins, spin_rate: float,
                 control_rate: float, logger: logging.Logger = log):
        self.robot_id = robot_id  # as AgentOptions spelled it, once: `/robot1` is robot1 there
        self.architecture = architecture
        self.bus = bus
        self.clock = clock
        self.log = logger
        self.ctx = AgentContext(self.robot_id, bus, clock,
                                rng if rng is not None else robot_rng(0, self.robot_id),
                                log=logger, architecture=architecture)
        self.plugins = plugins
        self.high_period = 1.0 / spin_rate
        self.ctrl_period = 1.0 / control_rate
        self._make_coordinator = make_coordinator
        self.coordinator = make_coordinator()
        self.team: set[str] = set()
        self.ignored_own = 0
        self.ignored_mismatch = 0
        self.ignored_strangers = 0
        self.ignored_outsiders = 0  # tokens and messages of robots off the roster
        self.ignored_other_instance = 0  # index-based messages counting in another instance
        # the digest of the robot's instance, stamped on its index-based messages ("": none)
        self.instance_digest = plugins.instance.digest if plugins.instance is not None else ""
        self.refused = 0
        self.injector = FaultInjector(robot_id, bus, clock, logger)  # `faults` sets its plan
        # teammates' coordination messages that reached this agent, by kind (whatever became of
        # them): the cost of what it subscribes to (docs/murdoch.md, Messages heard)
        self.received: collections.Counter[str] = collections.Counter()
        # what it refused (`_drop`; network threads add under _count_lock), what it last said
        # of it and when (tell_refusals)
        self.refusals = Refusals()
        self._refusals_told: dict = {}
        self._refusals_at = -math.inf
        self._last_drop_log: dict[str, float] = {}
        self._seq: dict[str, int] = collections.defaultdict(int)
        self._inbox = Inbox()  # filled by network callbacks, drained by the loop thread only
        self.tokens = TeamTokens()  # teammates' tokens, apart from the inbox (tokens.py)
        self._count_lock = threading.Lock()  # network callbacks' counters (`_drop`, `received`)
        self._handles: list = []  # subscriptions and the agent's token, closed at shutdown
        self._layers_task: str | None = None
        # tasks submitted at run time (growth.py): heard here, grown at a decision step
        self.run_time_tasks = RunTimeTasks(robot_id, clock, logger)
        self.ctx.refusal_sources.append(self.run_time_tasks.refusals)

    @property
    def faults(self) -> FaultPlan | None:
        """The faults injected into this agent, as resolved so far (`FaultInjector.plan`)."""
        return self.injector.plan

    @faults.setter
    def faults(self, plan: FaultPlan | None) -> None:
        """Set before `start`: the run's plan for this agent (mrta_zenoh.failure.plan_for)."""
        self.injector.give(plan)

    # ------------------------------------------------------------ set-up (py_trees' setup)
    def limit_team(self, team: Iterable[str] | None) -> None:
        """Only these robots (ids as AgentOptions spells them) may join the team; None: anyone
        holding the architecture's agent token (module docstring). Before `start`."""
        # the architecture's own processes (a dispatcher) are on every team: they join it
        # through their process token, never as robots
        self.roster = None if team is None else frozenset(
            [*team, self.robot_id, *self.architecture.processes])

    def start(self) -> None:
        """Plugins subscribe, then the agent listens to its teammates and their tokens."""
        self.advertised()  # a bad subject is a configuration error before anything starts
        self.plugins.setup(self.ctx)
        self._handles.extend(self.injector.listen(lambda: self.roster))
        arch = self.architecture
        if arch.takes_submitted:  # an architecture growing none hears none (costs nothing)
            self._handles.append(self.run_time_tasks.listen(self.bus))
        for kind in self.coordinator.listens:
            for key_expr in self.listen_keys(kind):
                self._handles.append(self.bus.subscribe(
                    key_expr, lambda s, k=kind: self._on_message(k, s),
                    msg_type=arch.messages[kind]))
        # subjects first: each watch asks for the tokens already there, and a teammate answers
        # the two questions in order on one link — so, as its subject tokens were declared
        # before its agent token, one that has the agent token has its subjects (await_team)
        if self.coordinator.hears_subjects():
            self._handles.append(self.bus.watch_liveliness(arch.key("*", SUBJECT, "*"),
                                                           self._on_subject_token))
        self._handles.append(self.bus.watch_liveliness(arch.agent_tokens, self._on_token))
        for name in arch.processes:
            if name != self.robot_id:
                self._handles.append(self.bus.watch_liveliness(
                    arch.process_token(name), lambda _k, alive, n=name: self.tokens.record(n, alive)))

    def listen_keys(self, kind: str) -> list[str]:
        """The key expressions the agent subscribes to for `kind`: every robot's, or only the
        coordinator's subjects (`Coordinator`). Read once at start: a coordinator rebuilt when
        time restarts has the same parameters, hence the same subjects."""
        subjects = self.coordinator.subjects(kind)
        if subjects is None:
            return [self.architecture.every(kind)]
        return [self.architecture.key("*", kind, self._chunk(subject, kind))
                for subject in subjects]

    def _chunk(self, subject: str, what: str) -> str:
        if not isinstance(subject, str) or not subject or any(c in subject for c in "/*$?#"):
            raise ConfigError(f"{self.robot_id}: subject {subject!r} of {what!r} is not one "
                              "key chunk")
        return subject

    def advertised(self) -> tuple[str, ...]:
        """The subjects the coordinator advertises (`Coordinator.advertises`), checked: each
        becomes one key chunk of a token."""
        return tuple(self._chunk(s, "advertises") for s in self.coordinator.advertises)

    def declare_alive(self) -> None:
        """Last step of start-up: alive means ready (docs/zenoh.md, the start-up race) — every
        subscription is declared before any token. The subject tokens go just before the
        agent's: a teammate does not count a subject before the robot's agent token anyway, and
        one link carries a session's declarations in order, so a teammate that has the agent
        token has its subjects too (`await_team` relies on it)."""
        arch = self.architecture
        for subject in self.advertised():
            self._handles.append(self.bus.declare_token(arch.key(self.robot_id, SUBJECT,
                                                                 subject)))
        self._handles.append(self.bus.declare_token(
            arch.process_token(self.robot_id) if self.is_process else
            arch.agent_token(self.robot_id)))

    @property
    def is_process(self) -> bool:
        """Whether this agent is one of the architecture's processes (a dispatcher), not a
        robot: its token is its process token, and it has no body to command."""
        return self.robot_id in self.architecture.processes

    def await_team(self, stop: threading.Event, limit: float = TEAM_WAIT) -> list[str]:
        """Before the first tick in lockstep: wait (wall time, at most `limit`) until every
        robot on the roster holds its agent token, and return those still missing. Tokens
        travel beside the steps, not in them: a teammate's token heard one tick later than in
        another run of the same seed changed what the run did (MURDOCH's auctioneer ranks, a
        first message dropped as a stranger's). The simulator waits for this participant's
        first answer meanwhile, so simulated time does not move. Out of lockstep, or without a
        roster (no --team), there is nothing to wait for."""
        if self.roster is None or not self.in_lockstep():
            return []
        deadline = time.monotonic() + limit
        while True:
            missing = self.tokens.missing(self.roster, self.robot_id)
            if not missing or stop.is_set() or time.monotonic() >= deadline:
                return missing
            stop.wait(0.01)

    def _outsider(self, key: str, robot: str, alive: bool) -> bool:
        """Whether a token of `robot` is off the roster (--team): ignored, its coming counted."""
        if self.roster is None or robot in self.roster:
            return False
        if alive:
            self._drop("ignored_outsiders", "ignoring %s: %s is not on the team (--team)", key,
                       robot, entry=("token", robot, OFF_ROSTER, False))
        return True

    def _on_token(self, key: str, alive: bool) -> None:
        """A teammate's token came or went: recorded for the loop thread, which owns the team."""
        robot = first_chunk(key)
        if robot in self.architecture.processes:
            return  # a process is on the team by its process token only, never as a robot
        if self._outsider(key, robot, alive):
            return
        self.tokens.record(robot, alive)

    def _on_subject_token(self, key: str, alive: bool) -> None:
        """A teammate's subject token came or went: recorded for the loop thread, which tells
        the coordinator once the robot is on the team (`TeamTokens.subjects_to_tell`)."""
        robot, subject = first_chunk(key), key.rsplit("/", 1)[-1]
        if robot == self.robot_id or self._outsider(key, robot, alive):
            return  # its own (the coordinator knows what it advertises), or an outsider's
        self.tokens.record_subject(robot, subject, alive)

    def _on_message(self, kind: str, sample: Sample) -> None:
        sender = first_chunk(sample.key)
        msg = sample.message
        if sender == self.robot_id:
            self.ignored_own += 1
            return
        with self._count_lock:  # network callbacks run on several threads
            self.received[kind] += 1
        if msg.header.frame_id.strip("/") != sender:
            self._drop("ignored_mismatch", "ignoring %s on %s with frame_id '%s'",
                       type(msg).__name__, sample.key, msg.header.frame_id,
                       entry=(kind, sender, MISMATCH, True))
            return
        if self.roster is not None and sender not in self.roster:
            self._drop("ignored_outsiders", "ignoring %s from %s, which is not on the team "
                       "(--team)", type(msg).__name__, sender, entry=(kind, sender, OFF_ROSTER,
                                                                      False))
            return
        if sender not in self.tokens.alive:  # before it takes inbox space (checked again at the tick)
            self._drop("ignored_strangers", "ignoring %s from %s, which holds no agent token",
                       type(msg).__name__, sender)
            return
        if isinstance(msg, IndexedMessage) and msg.instance != self.instance_digest:
            self._drop("ignored_other_instance", "ignoring %s from %s: it counts robots and "
                       "tasks in instance %s, this robot in %s — the team runs two instances",
                       type(msg).__name__, sender, msg.instance or "(none)",
                       self.instance_digest or "(none)",
                       entry=(kind, sender, OTHER_INSTANCE, False))
            return
        heard = self.injector.on_receipt(sample.key, msg.header.seq, sender,
                                         self.heard_at(msg.header.stamp))
        if heard is not None:  # else a fault dropped it (counted by the injector)
            self._inbox.put(Heard(heard, kind, sender, msg, sample.key))

    # ------------------------------------------------------------ the inbox
    def in_lockstep(self) -> bool:
        return self.clock.in_lockstep()

    def heard_at(self, stamp: float) -> float:
        """When a message stamped `stamp` counts as heard: in lockstep every robot shares one
        simulated time, so its own stamp, exact whatever the network did; otherwise now.
        An injected latency comes on top (`_on_message`)."""
        return stamp if self.in_lockstep() else self.clock.now()

    def take_due(self, now: float) -> list[Heard]:
        """Every queued message due at `now`, in order (`Inbox.take_due`)."""
        return self._inbox.take_due(now, self.in_lockstep(), self.injector.delayed)

    def _drop(self, counter: str, reason: str, *args,
              entry: tuple[str, str, str, bool] | None = None) -> None:
        """Count a dropped message in `counter` and, under `entry` (kind, sender, reason,
        forged), in what the agent says it refused; log at most one line per DROP_LOG_PERIOD
        wall seconds per counter, so a flood (a forger, a misconfigured teammate) cannot flood
        the log. Names from the network are shown escaped (mrta_zenoh.untrusted)."""
        with self._count_lock:  # network callbacks run on several threads
            if entry is not None:
                self.refusals.add(*entry)
        n = getattr(self, counter) + 1
        setattr(self, counter, n)
        wall = time.monotonic()
        last = self._last_drop_log.get(counter)
        if last is None or wall - last >= DROP_LOG_PERIOD:
            self._last_drop_log[counter] = wall
            self.log.warning("%s: " + reason + " (%d so far)", self.robot_id,
                             *(visible(a, 200) if isinstance(a, str) else a for a in args), n)

    # ------------------------------------------------------------ one decision step
    def tell_refusals(self, now: float, final: bool = False) -> None:
        """Say what this agent refused (module docstring), when it changed — at most every
        TALLY_PERIOD, or now as it stops. Nothing refused, nothing said."""
        if not final and now < self._refusals_at + TALLY_PERIOD:
            return
        with self._count_lock:
            heard = collections.Counter(self.coordinator.refusals())
            for source in self.ctx.refusal_sources:  # the plugins' (AgentContext)
                heard.update(source())
            counts = self.refusals.merged(heard)
        if counts == self._refusals_told:
            return
        self._refusals_told, self._refusals_at = counts, now
        header = Header(frame_id=self.robot_id, stamp=now, seq=1)
        self.bus.publish(refused_key(self.robot_id), tally(header, counts))

    def tick_high(self, now: float) -> None:
        changes, subject_changes = self.tokens.take()
        for robot, alive in sorted(changes.items()):  # not the network's order
            if robot != self.robot_id and (robot in self.team) != alive:
                (self.team.add if alive else self.team.discard)(robot)
                self.coordinator.teammate(robot, alive)
        if changes or subject_changes:  # what changed of the team's subjects (tokens.py)
            for robot, subject, held in self.tokens.subjects_to_tell(
                    set(changes) | {r for r, _ in subject_changes}, subject_changes, self.team):
                self.coordinator.teammate_subject(robot, subject, held)
        for item in self.take_due(now):
            what = item.message
            if self.injector.cut(item.sender, what.header.stamp, item.at):
                continue
            if item.sender not in self.team:
                self._drop("ignored_strangers", "ignoring %s from %s, which holds no agent token",
                           type(what).__name__, item.sender)
                continue
            self.injector.heard_late(item.key, what.header.seq)
            if not self.coordinator.hear(item.kind, item.sender, what, item.at):
                # not taken: ALLIANCE's broadcast of a task this robot does not serve is no
                # evidence; what is, the logic counts under its reason (Coordinator.refuse)
                self._drop("refused", "refused %s from %s", type(what).__name__, item.sender)
        self.run_time_tasks.take(now, self.plugins, self.ctx, self.coordinator)
        for say in self.coordinator.tick(now):
            self.send(say, now)
        self.switch_layers(self.coordinator.active_task, now)
        self.injector.announce(now, self.coordinator.active_task)
        self.tell_refusals(now)

    def send(self, say: Say, now: float) -> None:
        key = self.architecture.key(self.robot_id, say.kind,
                                    *((say.subkey,) if say.subkey is not None else ()))
        self._seq[key] += 1
        if say.watched and self._seq[key] == 1:
            self.bus.leave_unclaimed(key)
        header = Header(frame_id=self.robot_id, stamp=now, seq=self._seq[key])
        kind = self.architecture.messages[say.kind]
        stamped = {"instance": self.instance_digest} if issubclass(kind, IndexedMessage) else {}
        self.bus.publish(key, say.message(self.architecture.messages, header, **stamped),
                         lossy=say.lossy)

    @property
    def active_task(self) -> str | None:
        """The task whose layers run: the decision logic's choice as of its last tick."""
        return self._layers_task

    # ------------------------------------------------------------ the active task's layers
    def layers_of(self, task: str | None) -> list[Layer]:
        if task is None or self.stalled:
            return []
        return self.plugins.layers.get(task, [])

    def stall(self, now: float) -> None:
        """The stall fault: the running layers stop and the robot stands still, for good; the
        decision logic goes on (its token, its broadcasts or lease renewals), so only what
        watches progress — ALLIANCE's φ and ψ — can tell."""
        self.log.warning("%s: stalling %s as asked (fault injection): alive, stuck",
                         self.robot_id, at(now))
        for layer in self.layers_of(self.active_task):
            layer.on_deactivate(now)
        self.stalled = True
        if not self.is_process:
            self.ctx.publish_cmd(0.0, 0.0)

    def switch_layers(self, task: str | None, now: float) -> None:
        """Make `task`'s layers the running ones: terminate the old task's layers, initialise
        the new ones (py_trees' terminate / initialise). The driver, not the logic, remembers
        which task's layers run, so a logic active from its first tick starts them too."""
        if task == self._layers_task:
            return
        for layer in self.layers_of(self._layers_task):
            layer.on_deactivate(now)
        self._layers_task = task
        for layer in self.layers_of(task):
            layer.on_activate(now)

    def step_layers(self, now: float, dt: float) -> None:
        for layer in self.layers_of(self.active_task):
            layer.step(now, dt)

    def restart(self, now: float) -> None:
        """Time restarted (a new simulation run): the old run's world is gone — layers
        deactivated, sensors forgotten, queued messages dropped, the decision logic built
        afresh (it keeps knowing who is on the team: tokens do not restart)."""
        self.log.warning("%s: time restarted at t=%.2f (a new simulation run): starting afresh",
                         self.robot_id, now)
        for layer in self.layers_of(self.active_task):
            layer.on_deactivate(now)
        self._layers_task = None
        self.stalled = False  # a new run: the stall strikes again at its time
        for sensor in self.plugins.sensors.values():
            sensor.forget()
        self._inbox.clear()
        self.injector.restart()  # an @first fault is resolved again, the tally counts afresh
        with self._count_lock:
            self.refusals = Refusals()  # counted afresh, like the fault tally
        self._refusals_told, self._refusals_at = {}, -math.inf
        self.coordinator = self._make_coordinator()
        self.run_time_tasks.retell(self.coordinator)
        for robot in sorted(self.team):
            self.coordinator.teammate(robot, True)
        for robot, subjects in sorted(self.tokens.told_subjects.items()):
            for subject in sorted(subjects):
                self.coordinator.teammate_subject(robot, subject, True)

    def on_crash(self, now: float) -> None:
        """The crash fault strikes: the process dies (SIGKILL), its tokens with its session. An
        agent host replaces this with a crash of this robot alone (runtime.agent_host)."""
        crash_now(self.robot_id, now, self.log)

    def withdraw(self) -> None:
        """This robot crashed in an agent host: its tokens and subscriptions go, as with its
        process — no zero-velocity command, no final tally, no plugin shutdown."""
        self.withdrawn = True
        self._close_handles()

    def hears_alive(self, robot: str) -> bool:
        """Whether `robot`'s agent token is alive as this agent's callbacks heard it."""
        return self.tokens.hears_alive(robot)

    def shutdown(self) -> None:
        """Stop the robot: deactivate the running layers, command zero velocity, let every
        plugin close what it opened (py_trees' terminate, then shutdown), stop listening."""
        self.injector.final_tally()
        now = self.clock.now()
        self.tell_refusals(now, final=True)
        for layer in self.layers_of(self.active_task):
            layer.on_deactivate(now)
        if not self.is_process:
            self.ctx.publish_cmd(0.0, 0.0)
        self.plugins.shutdown()
        self._close_handles()

    def _close_handles(self) -> None:
        """Stop listening and withdraw its tokens (shutdown, or a crash in a host)."""
        for h in self._handles:
            h.close()
        self._handles.clear()

    # ------------------------------------------------------------ the loop
    def run(self, stop: threading.Event, until: float | None = None) -> None:
        """Run until stopped, or until the clock passes `until`: sleep on the injected clock
        until each wake-up `schedule` asks for."""
        for t in self.schedule(until):
            if stop.is_set() or not self.clock.sleep_until(t, stop):
                break

    def schedule(self, until: float | None = None) -> Iterator[float]:
        """The loop itself, as a generator: yields the next time it must wake at, and does the
        work due once resumed at that time. `run` sleeps between the two; a virtual-time
        harness (tests/harness/alliance_team.py) sets a manual clock instead, so tests drive this very
        loop — its rates, its catch-up rule, fault injection, a restart of time — rather than a
        copy of it."""
        high_period, ctrl_period = self.high_period, self.ctrl_period
        now = self.clock.now()
        next_high, next_ctrl, last_ctrl = now, now, now
        epoch = self.clock.restarts
        while True:
            t = min(next_high, next_ctrl)
            if until is not None and t > until:
                return
            yield t
            now = self.clock.now()
            strike = self.injector.strikes(now)
            if strike is FaultKind.CRASH:
                self.on_crash(now)  # a real crash: no shutdown, no goodbye
            if strike is FaultKind.STALL and not self.stalled:
                self.stall(now)
            if self.clock.restarts != epoch:
                epoch = self.clock.restarts
                self.restart(now)
                next_high, next_ctrl, last_ctrl = now, now, now
                if until is not None:
                    until = now + (until - t)
            if now >= next_high - EPSILON:
                self.tick_high(now)
                self.injector.tally(now)
                next_high += high_period
                if next_high <= now:  # fell behind: skip, don't burst
                    next_high = now + high_period
            if now >= next_ctrl - EPSILON:
                self.step_layers(now, now - last_ctrl)
                last_ctrl = now
                next_ctrl += ctrl_period
                if next_ctrl <= now:
                    next_ctrl = now + ctrl_period
