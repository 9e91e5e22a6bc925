"""Starting a process of a run, one way for every process (ros2cli's `NodeStrategy`).

Every process on the bus — a robot's agent, the simulator, the supervisor, the recorder and
viewer, a ROS 2 bridge, the mission runner, and a process that is neither robot nor observer
(a task dispatcher: a role of its own, a token of its own, simulated time, a lockstep
participant) — starts through `Node`, in this order:

1. `faulthandler` on: a crash in a C extension (zenoh, pymunk, numpy) prints every thread's
   Python stack to stderr, which the launch and mission runners keep in the run's log;
2. the identity check (mrta_zenoh.identity): a fleet certificate that is not this process's
   is refused before anything opens (ConfigError, exit 2);
3. the clock: wall time (`WALL`), the simulator's (`SIM`: a SimClock following `clock`), or
   lockstep (`LOCKSTEP`: a participant named after the node, which a lockstep simulator
   waits for at every step it has something due — mrta_zenoh.lockstep);
4. signals: SIGINT and SIGTERM set `node.stop` (lifecycle.stop_on_signals), so the process
   leaves its `with` blocks and closes its session cleanly;
5. the bus: opened from the options, or one the caller opened (tests' in-process bus), which
   is left open;
6. on simulated time, the clock follows the simulator (`follow_sim_clock`); in lockstep the
   node joins the barrier: its participant token goes out before whatever the process declares
   next, so "alive" (its own token, declared last through `declare_alive`) means "ready".

Leaving the `with` closes everything in reverse order: what the process held through the node
(`hold`, `declare_alive`), the barrier, the clock's subscriptions, the session, the signal
handlers.
"""

from __future__ import annotations

import contextlib
import enum
import faulthandler
import sys
import threading
from collections.abc import Sequence
from typing import Any

from .bus import Bus, BusOptions, open_bus
from .clock import Clock, SimClock, WallClock, follow_sim_clock
from .identity import check_identity
from .lifecycle import stop_on_signals


class NodeTime(str, enum.Enum):
    WALL = "wall"            # the machine's clock
    SIM = "sim"              # the simulator's, followed (observers: supervisor, recorder)
    LOCKSTEP = "lockstep"    # the simulator's, as a lockstep participant (agents, a dispatcher)

    def __str__(self) -> str:
        return self.value


def enable_faulthandler() -> None:
    """Print every thread's Python stack on a fatal signal (SIGSEGV, SIGABRT, …), to stderr.
    Left as it is when already on (pytest turns it on with its own file). Without a file
    descriptor behind stderr there is nowhere a C-level handler could write, so it stays off."""
    if faulthandler.is_enabled():
        return
    try:
        sys.stderr.fileno()
    except (AttributeError, OSError, ValueError):  # io.UnsupportedOperation is both
        return
    faulthandler.enable(sys.stderr)


class Node:
    """One process's start-up and shutdown (module docstring). `role`: robot, observer, bridge
    or a registered role (`simulator`, a dispatcher's); `name`: the process's name — a robot's
    id, a dispatcher's name — checked against its certificate and, in lockstep, its
    participant id; `robots`: a bridge's robots; `stop`: an event to stop on besides the
    signals (tests, a caller's thread); `bus`: an open bus to use instead of opening one (its
    caller's to close; no identity is checked: it was opened elsewhere); `speaks_for`: in lockstep,
    the robots this participant answers for besides itself (an agent host's)."""

    def __init__(self, bus_options: BusOptions, role: str, *, name: str | None = None,
                 robots: Sequence[str] = (), time: NodeTime = NodeTime.WALL,
                 stop: threading.Event | None = None, bus: Bus | None = None,
                 speaks_for: Sequence[str] = ()) -> None:
        enable_faulthandler()
        time = NodeTime(time)
        if time is NodeTime.LOCKSTEP and not name:
            raise ValueError("a lockstep participant needs a name")
        if bus is None:
            check_identity(bus_options, role, name, tuple(robots))
        self.bus_options, self.role, self.name, self.time = bus_options, role, name, time
        self.clock: Clock = (_lockstep_clock(name, tuple(speaks_for))
                             if time is NodeTime.LOCKSTEP
                             else SimClock() if time is NodeTime.SIM else WallClock())
        self._given_bus = bus
        self._stack: contextlib.ExitStack | None = None
        self.stop = stop or threading.Event()
        self.bus: Bus | None = bus

    @property
    def sim_time(self) -> bool:
        return self.time is not NodeTime.WALL

    def __enter__(self) -> Node:
        with contextlib.ExitStack() as stack:  # a failure half-way closes what was opened
            stack.enter_context(stop_on_signals(self.stop))
            self.bus = (self._given_bus if self._given_bus is not None
                        else stack.enter_context(open_bus(self.bus_options)))
            if self.sim_time:
                stack.enter_context(follow_sim_clock(self.bus, self.clock))
            if self.time is NodeTime.LOCKSTEP:
                stack.enter_context(self.clock.join(self.bus))
            self._stack = stack.pop_all()
        return self

    def __exit__(self, *exc: object) -> None:
        stack, self._stack = self._stack, None
        if stack is not None:
            stack.close()

    def hold(self, resource: Any) -> Any:
        """Keep `resource` (a context manager: a subscription, a token, a file) until the node
        closes, before its bus."""
        return self._stack.enter_context(resource)

    def declare_alive(self, key: str) -> None:
        """This process's own liveliness token, held until the node closes. Declare it last:
        every subscription before it, so "alive" means "ready" (docs/zenoh.md, the start-up
        race)."""
        self.hold(self.bus.declare_token(key))

    def wait_for_clock(self) -> bool:
        """On simulated time, block until the first clock sample (True) or `stop` (False); on
        wall time, True at once."""
        if not self.sim_time:
            return True
        while not self.clock.started.wait(0.1):
            if self.stop.is_set():
                return False
        return True


def _lockstep_clock(name: str, speaks_for: tuple[str, ...]) -> Clock:
    """A participant's clock, its module loaded only by a participant: an observer (supervisor,
    recorder) starts a node too and must not load the participant's books (the lockstep
    package's own lazy loading, mrta_zenoh.lockstep)."""
    from .lockstep.participant import LockstepClock
    return LockstepClock(name, speaks_for=speaks_for)
