"""A mission run's processes as the runner watches them: who is up (`Readiness`, from
liveliness tokens, never from log lines) and whether the run is what its seed says and its
summary covers all of it (`RunWatch`).

A run is *disturbed* when a process of the run lost its liveliness token while the run was on —
stopped (SIGSTOP, a debugger, a laptop's lid, a machine too busy to run it) past its Zenoh
lease, or cut off from the bus — other than a crash the run injected: lockstep no longer waits for a participant without a
token, so the run went on without it, and its outcome depends on when the process was stopped,
not on the seed. It is *incomplete* when its recording does not cover the whole mission: the
recorder lost its session (what was published meanwhile never reached the file), or the file
ends before the mission's duration. Either way the summary is not that of the run the seed
describes: `summary.json` says what happened (`run_status`, `disturbances`, `recorded_until`),
lockstep runs are not called exact, `mrta demo` exits 1 on an incomplete summary, and
`mrta experiment` runs such a run again. A process of the run that *ended* before the run did
(a dispatcher or a recorder SIGKILLed from outside, an agent that exited with an error; not a
crash the run injected) is such a disturbance too, its entry saying how it ended (`ended`,
`ended_early`): the summary is still written from what was recorded — even from an empty
recording — where the runner used to raise and write none, and `mrta demo` prints it and
exits 1. (A process that fails before every process is up is a start-up failure: no run.)

Whose tokens: each robot's agent token (the architecture's `agent_tokens`), every lockstep
participant's (agents, and any other participant: a dispatcher), the recorder's and the
simulator's clock source — a process is up while any of its tokens lives. A token under a name
that is no process of the run (a stranger's participant token, a robot off the team) is no
disturbance: `strangers` reports it apart — one stranger on a shared bus must not make every
run inexact (and `mrta experiment` run it again and again). What is no
disturbance: the final loss of a crash target whose process died by a SIGKILL this runner did
not send (the crash itself), and the simulator's token going at the end of its run (the runner
checks that it then exits cleanly, or by the SIGTERM the runner sent it once the work was done),
nor a token seen going and coming back before the run's clock moved (at 0 s: Zenoh may report a
process's token twice as its session joins the bus, and no simulated time passed meanwhile).

Nor is the runner's own blindness: when the run's router closes the runner's link (on a busy
machine the runner may read too slowly for a while), the runner is told every token went and,
once it reconnected, that every token is back — no process lost anything. Such losses, each
back within BLIND_SLACK of the link's reopening, are counted (`unseen`, logged), not reported
(bus.watch_router_link; measured in the README's 20-robot walkthrough at load 25: three times in
21 min every process "lost its token" at one instant and was back at the same simulated time).
Why readers were cut at all: Zenoh closes a link whose reliable samples wait to be queued past
`wait_before_close` (5 s by default); ours is lockstep's wait for a live participant
(bus/options.py), so a slow reader on a busy machine is waited for, not cut.

The lease is the run's (runner.run_lease): in lockstep, lockstep's wait for a live
participant (30 s) — at load 25 the 3 s default dropped a recorder starved of CPU, which missed
a delivery, and the README's walkthrough exited 1 (issue 51) — otherwise 3 s. Not seen here: a
process stopped for less than the lease keeps its session. In lockstep a stopped agent or
simulator is waited for, so the run is unchanged; a recorder stopped that briefly holds the
publishers of reliable keys back and loses nothing of them — every key the summary's
allocation, deliveries, coordination counts and liveliness are read from — but may miss
best-effort samples (the clock, sensors, ALLIANCE's sensory feedback), which changes only the
whole bus's message count (`messages.total`: the machine's, like wall time, not the seed's).
"""

from __future__ import annotations

import contextlib
import os
import signal
import threading
import time
from typing import Callable

import msgspec

from mrta_zenoh import keys
from mrta_zenoh.architectures import Architecture
from mrta_zenoh.clock import Clock
from mrta_zenoh.errors import Interrupted, MrtaRuntimeError
from mrta_zenoh.lifecycle import Closing
from mrta_zenoh.lockstep.protocol import PARTICIPANT
from mrta_zenoh.presence import RobotPresence
from mrta_zenoh.processes import Child, ProcessGroup
from mrta_zenoh.untrusted import visible

from .summary import COMPLETE, DISTURBED, END_SLACK, INCOMPLETE, Disturbance

READY_TIMEOUT = 60.0  # wall seconds for every process to come up, on an idle machine
RECORDER = "recorder"
SIMULATOR = "simulator"
MAX_STRANGERS = 20  # strangers' names a summary lists
MAX_NAME = 60       # characters of a stranger's name kept


def ready_timeout(load: float, cores: int) -> float:
    """How long a process of the run may take to come up: READY_TIMEOUT stretched by how many
    runnable processes share each core (the 1-minute load average per core, at least 1). A
    process given a tenth of a core starts ten times slower: the recorder of a 100-robot run
    (reading a 22.8 MB application file) did not come up within 60 s at load 29 on 2 cores
    though it was starting, not hung (issue 47), and the run failed. A hung process is still
    found — later on a busy machine."""
    return READY_TIMEOUT * max(1.0, load / max(cores, 1))


class Readiness(Closing):
    """Who is up, from liveliness tokens: the robots (RobotPresence), the recorder and the clock
    source (tokens under @mrta/…, which `**` does not match)."""

    def __init__(self, bus, robots: list[str]):
        self.recorder = threading.Event()
        self.clock = threading.Event()
        self._stack = contextlib.ExitStack()
        self.presence = self._stack.enter_context(RobotPresence(bus, robots))
        for prefix, event in ((keys.RECORDER_TOKEN, self.recorder),
                              (keys.CLOCK_SOURCE_TOKEN, self.clock)):
            self._stack.callback(bus.watch_liveliness(
                prefix + "/**", lambda k, up, e=event: up and e.set()).close)

    def robots_up(self) -> bool:
        return self.presence.all_up()

    def wait(self, what: Callable[[], bool], label: str, group: ProcessGroup,
             stop: threading.Event, ignore: Callable[[], list[str]] = list,
             progress: Callable[[], object] = lambda: None) -> None:
        """Until `what()`; a child of `group` that failed meanwhile is an error, but those
        `ignore()` names (subjects of a crash the run injected). Given up after `limit`
        (ready_timeout: stretched by the load) with no `progress()` change: twenty agents
        starting on a busy machine come up one by one over more than a minute (the README's
        walkthrough at load 25: 55 s, then > 60 s and no run) — while they still come, the
        start is slow, not stuck."""
        limit = ready_timeout(os.getloadavg()[0], os.cpu_count() or 1)
        seen = progress()
        deadline = time.monotonic() + limit
        while not what():
            now = progress()
            if now != seen:
                seen, deadline = now, time.monotonic() + limit
            if stop.is_set():  # first: after a Ctrl-C, children ended by it did not fail
                group.interrupted()
                raise Interrupted()
            failed = group.failed(ignore=ignore())
            if failed:
                raise MrtaRuntimeError(f"{failed[0].name} failed while starting (it "
                                       f"{failed[0].describe_exit()}):\n{failed[0].tail()}")
            if time.monotonic() > deadline:
                raise MrtaRuntimeError(f"{label} did not come up: nothing more came up "
                                       f"within {limit:.0f} s")
            stop.wait(0.05)

    def close(self) -> None:
        self._stack.close()


class RunWatch(Closing):
    """The tokens of a run's processes, watched from the runner from before the first process
    starts until `end()` (the simulator's process ended): each loss and return, in the runner's
    simulated time. A context manager (closes the watches)."""

    def __init__(self, bus, arch: Architecture, clock: Clock, wall=time.monotonic) -> None:
        self._clock = clock
        self._wall = wall
        self._lock = threading.Lock()
        self._judging = True
        self._held: dict[str, set[str]] = {}
        # per process, each loss: [lost_at, back_at] in simulated time, and the same in wall
        self._events: dict[str, list[list[float | None]]] = {}
        self._walls: dict[str, list[list[float | None]]] = {}
        # this process's own link to the run's router: the wall times it closed and reopened
        # (module docstring: a blind runner sees every token go)
        self._blind: list[list[float | None]] = []
        self.unseen = 0  # losses that were this runner's blindness, not the process's
        naming = ((arch.agent_tokens, keys.first_chunk),
                  (f"{PARTICIPANT}/*", _last_chunk),
                  (f"{keys.RECORDER_TOKEN}/*", lambda _: RECORDER),
                  (f"{keys.CLOCK_SOURCE_TOKEN}/*", lambda _: SIMULATOR))
        self._watches = [bus.watch_router_link(self._on_router_link)]
        self._watches += [bus.watch_liveliness(expr, lambda key, alive, name=name:
                                               self._on_token(name(key), key, alive))
                          for expr, name in naming]

    def _on_router_link(self, up: bool) -> None:
        now = self._wall()
        with self._lock:
            if not up:
                self._blind.append([now, None])
            elif self._blind and self._blind[-1][1] is None:
                self._blind[-1][1] = now

    def _on_token(self, process: str, key: str, alive: bool) -> None:
        now = self._clock.now()
        with self._lock:
            if not self._judging:
                return
            held = self._held.setdefault(process, set())
            was_up = bool(held)
            (held.add if alive else held.discard)(key)
            events = self._events.setdefault(process, [])
            walls = self._walls.setdefault(process, [])
            if was_up and not held:
                events.append([now, None])
                walls.append([self._wall(), None])
            elif held and not was_up and events and events[-1][1] is None:
                events[-1][1] = now
                walls[-1][1] = self._wall()

    def end(self) -> None:
        """The run is over: what goes from now on is its processes ending."""
        with self._lock:
            self._judging = False

    def disturbances(self, struck: Callable[[str], bool],
                     processes: set[str] | None = None) -> list[Disturbance]:
        """Every loss that was no crash the run injected nor the simulator's end (module
        docstring). `struck(process)`: whether that process (a robot id for an agent) is a
        crash target whose crash struck as injected (its process crashed itself,
        `crashed_itself`; a hosted robot's is told by its host, supervisor hosting);
        `processes`: the names of the run's processes (None: every name seen is one; the
        recorder and the simulator always are) — another's loss is a stranger's, no
        disturbance."""
        out = []
        with self._lock:
            events = {p: [list(e) for e in es] for p, es in self._events.items()
                      if _of_the_run(p, processes)}
            walls = {p: [list(w) for w in self._walls[p]] for p in events}
            blind = [list(b) for b in self._blind]
        unseen = 0
        for process, lost in sorted(events.items()):
            for i, (lost_at, back_at) in enumerate(lost):
                final = back_at is None and i == len(lost) - 1
                if final and (process == SIMULATOR or (
                        struck(process))):
                    continue
                if back_at is not None and back_at <= 0.0:  # back before the run was on
                    continue
                if back_at is not None and _while_blind(walls[process][i], blind):
                    unseen += 1  # this runner's link went, not the process's
                    continue
                out.append(Disturbance(process, round(lost_at, 2),
                                       None if back_at is None else round(back_at, 2)))
        self.unseen = unseen
        return out

    def strangers(self, processes: set[str]) -> list[str]:
        """The names whose tokens came while the run was on and that are none of `processes`
        (module docstring), escaped, at most MAX_STRANGERS."""
        with self._lock:
            names = sorted(p for p in self._held if not _of_the_run(p, processes))
        return [visible(n, MAX_NAME) for n in names[:MAX_STRANGERS]]

    def close(self) -> None:
        for w in self._watches:
            w.close()


BLIND_SLACK = 1.0  # wall s: a token's loss and its link's close are told apart by milliseconds


def _while_blind(wall: list[float | None], blind: list[list[float | None]]) -> bool:
    """Whether a token that went at wall[0] and came back at wall[1] did so across a close of
    this runner's own router link: the router told it every token had gone as the link
    closed, and told it them again as it reopened (measured: the tokens' losses a few ms
    before the link's close, their returns just after it reopened)."""
    lost, back = wall
    return back is not None and any(
        opened is not None and closed - BLIND_SLACK <= lost <= opened
        and back <= opened + BLIND_SLACK for closed, opened in blind)


def _of_the_run(process: str, processes: set[str] | None) -> bool:
    return processes is None or process in processes or process in (RECORDER, SIMULATOR)


def _last_chunk(key: str) -> str:
    return key.rsplit("/", 1)[-1]


def ended_early(disturbances: list[Disturbance], ended: dict[str, str], at: float
                ) -> list[Disturbance]:
    """`disturbances` with each process of the run that ended by itself before the run did —
    `ended`: process name → how (a SIGKILL from outside, an exit with an error; a crash the run
    injected is not one) — marked so: its last loss of its token says how it ended, or, when
    none was seen (it ended as the run did, or before its token was watched), a loss at `at`
    is added. The run is then disturbed (incomplete if it was the recorder), and its summary is
    still written from what was recorded: it used to end in an error and no summary at all."""
    out = [msgspec.structs.replace(d) for d in disturbances]
    for process, how in sorted(ended.items()):
        last = next((d for d in reversed(out) if d.process == process and d.back_at is None),
                    None)
        if last is None:
            out.append(Disturbance(process, round(at, 2), ended=how))
        else:
            last.ended = how
    return out


def crashed_itself(child: Child | None) -> bool:
    """Ended by a SIGKILL nobody here sent: the crash a fault injected (mrta_zenoh.failure)."""
    return (child is not None and child.returncode == -signal.SIGKILL
            and signal.SIGKILL not in child.signalled)


def check_simulator_end(sim: Child) -> None:
    """The simulator's end is the run's: an exit of its own with code 0, or the end of the
    SIGTERM the runner sent it once the mission's work was done (mission._watch). That signal
    may reach it as it is already shutting down at its duration, past its own signal handling,
    so that it dies by it: the work was done, and the recording is the recorder's, so that is a
    normal end too. Anything else is a MrtaRuntimeError naming how it ended."""
    if sim.failed():
        raise MrtaRuntimeError(f"the simulator {sim.describe_exit()}:\n" + sim.tail())


def run_status(disturbances: list[Disturbance], recorded_until: float | None,
               duration: float) -> str:
    """complete, disturbed or incomplete (module docstring)."""
    if recorded_until is None or recorded_until < duration - END_SLACK or any(
            d.process == RECORDER for d in disturbances):
        return INCOMPLETE
    return DISTURBED if disturbances else COMPLETE
