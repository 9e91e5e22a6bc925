"""The supervisor as a library: what `mrta supervise` does, and what other tools reuse
(resolve an application, attach a Supervisor to a bus)."""

from __future__ import annotations

import logging
import threading
import time
from collections import defaultdict
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

from mrta_zenoh import jsonsafe
from mrta_zenoh.bus import Bus, BusOptions
from mrta_zenoh.errors import ConfigError
from mrta_zenoh.identity import OBSERVER
from mrta_zenoh.keys import NODE_TOKEN, ROS2_BRIDGE_TOKEN
from mrta_zenoh.lockstep.protocol import STATUS, LockstepStatus
from mrta_zenoh.node import Node, NodeTime
from mrta_zenoh.tasks.messages import CHANGE, HISTORY, Change
from mrta_zenoh.tasks.server import TOKEN as INTAKE_TOKEN
from mrta_zenoh.architectures import architecture, architecture_names
from mrta_zenoh.toolchain.model import ApplicationFile, ArchitectureFile
from mrta_zenoh.toolchain.registry import Registry
from mrta_zenoh.toolchain.xmlio import load_rqt_mrta

from .entities import Serving
from .state import Supervisor
from ..mission.hook import application_watch

log = logging.getLogger("mrta.supervisor")
CLOCK_STALL = 2.0  # wall seconds without a clock sample: the `clock_stopped` alarm
HISTORY_WAIT = 2.0  # wall s the intake's task set so far is waited for (none: no run yet)


def to_json(snapshot: dict) -> str:
    """Always valid JSON: a non-finite number (which no valid input should produce) is null."""
    return jsonsafe.dumps(snapshot, nonfinite=lambda _: None)


def resolve_application(spec: str | None, registry: Registry | None = None,
                        ) -> tuple[ApplicationFile, ArchitectureFile]:
    """An application by name (registry) or by path, and the architecture it names. No name
    (None) means the only registered application: the framework knows none by name, and with
    several a guess would silently read the wrong monitors."""
    reg = registry or Registry()
    if spec is None:
        spec = only_application(reg)
    path = Path(spec)
    if path.is_dir():
        path = path / "rqt_mrta.xml"
    if path.suffix == ".xml" and path.is_file():
        app = load_rqt_mrta(path)
        if not isinstance(app, ApplicationFile):
            raise ConfigError("not an application file", file=str(path))
    else:
        _, app = reg.application(spec)
    _, arch = reg.architecture(app.architecture)
    return app, arch


def only_application(registry: Registry) -> str:
    """The package name of the one registered application; bad input if there are none or
    several (the user must say which)."""
    names = sorted(p.name for p, _ in registry.applications())
    if len(names) != 1:
        raise ConfigError("give the application (--app NAME or a path to its rqt_mrta.xml): "
                          + (f"{len(names)} are registered ({', '.join(names)})" if names
                             else "none is registered"))
    return names[0]


def ask_history(sup: Supervisor, bus: Bus, clock) -> None:
    """The intake's task set so far (`tasks/history`), taken as live changes are (a change
    heard both ways counts once: Supervisor.on_change). Asked when the intake's token is seen,
    not at once: a session just opened has not heard of the intake's queryable yet (declared
    before that token), and a view started before the run asks when its intake comes up."""
    try:
        bus.query(HISTORY, lambda s: sup.on_change(s.message, clock.now()), msg_type=Change,
                  timeout=HISTORY_WAIT)
    except Exception as exc:  # noqa: BLE001 - a thread of its own: say it, never die silently
        if not bus.closed:
            log.warning("the task intake's history could not be asked for: %s", exc)


def attach(sup: Supervisor, bus: Bus, clock, *, shown: bool = True) -> list:
    """Subscribe once per key expression for the monitors that read it, and to the
    application's task news (its TaskWatch), and watch liveliness. Not `shown` (a mission
    runner with no view of it: `mrta -q demo`, every run of a study): the task news alone,
    which is what tells the runner that every task is done (Supervisor.all_done), and the
    intake's `tasks/change` (tasks submitted at run time: Supervisor.on_change) — the
    monitors' samples (ALLIANCE's motivations: N² a second) would be decoded for nobody."""
    handles = [bus.subscribe(key_expr, lambda s: sup.on_task_sample(s.key, s.message,
                                                                    clock.now()),
                             msg_type=msg_type)
               for key_expr, msg_type in (sup.watch.feed() if sup.watch is not None else ())]
    handles.append(bus.subscribe(CHANGE, lambda s: sup.on_change(s.message, clock.now()),
                                 msg_type=Change))  # tasks submitted at run time
    handles.append(bus.watch_liveliness(INTAKE_TOKEN, lambda _key, up: up and threading.Thread(
        target=ask_history, args=(sup, bus, clock), name="mrta-task-history",
        daemon=True).start()))  # … and those that entered before this process listened
    if not shown:
        return handles
    by_key = defaultdict(list)
    for m in sup.monitors:
        by_key[m.key_expr].append(m)
    for key_expr, monitors in by_key.items():
        handles.append(bus.subscribe(key_expr, sup.handler_for(monitors, clock.now)))
    for key_expr, msg_type in sup.serving.feed() if sup.serving is not None else ():
        handles.append(bus.subscribe(key_expr, lambda s: sup.on_doing_sample(
            s.key, s.message, clock.now()), msg_type=msg_type))
    handles.append(bus.watch_liveliness("**", lambda k, alive: sup.on_liveliness(k, alive,
                                                                                clock.now())))
    # the ROS 2 graph (rmw_zenoh's tokens): an `@` chunk is matched only literally; and the
    # bridges, which say which robots are driven through ROS 2
    handles.append(bus.watch_absolute(sup.ros2.key_expr, lambda k, alive: sup.on_ros2_token(
        k, alive, clock.now())))
    handles.append(bus.watch_liveliness(f"{ROS2_BRIDGE_TOKEN}/*", lambda k, alive:
                                        sup.on_bridge_token(k, alive, clock.now())))
    # processes that are neither robot nor observer (central's dispatcher)
    handles.append(bus.watch_liveliness(f"{NODE_TOKEN}/*", lambda k, alive:
                                        sup.on_process_token(k, alive, clock.now())))
    handles.append(bus.subscribe(STATUS, lambda s: sup.on_lockstep(
        s.message.unresponsive, clock.now(), s.message.rivals, s.message.dropped),
        msg_type=LockstepStatus))
    return handles


def serving_of(name: str) -> Serving | None:
    """The registered architecture's own reports of which task each robot serves; None for an
    architecture file with no registered contract: its monitors are all there is to show."""
    return Serving(architecture(name)) if name in architecture_names() else None


class Refresh:
    """One refresh of a Supervisor at its clock's time: what every tool that shows one does
    (`mrta supervise`, `mrta view`, the patrol demo). On simulation time a new run (time
    restarted) starts the picture afresh, a clock that stopped raises `clock_stopped`, and a
    run that ended (its source's token is gone: SimClock.ended) raises nothing — the end of a
    run is no fault. The cadence is the caller's, in wall time even on simulation time, so that
    a simulator that stops or restarts is noticed instead of freezing the picture."""

    def __init__(self, sup: Supervisor, clock, sim_time: bool):
        self.sup, self.clock, self.sim_time = sup, clock, sim_time
        self._restarts = 0
        if sim_time:
            sup.source_gone = clock.ended

    def __call__(self) -> float:
        now = self.clock.now()
        if self.sim_time:
            if self.clock.restarts != self._restarts:
                self._restarts = self.clock.restarts
                self.sup.restart(now)
            self.sup.on_clock(self.clock.stalled(CLOCK_STALL), now, ended=self.clock.ended())
        self.sup.update(now)
        return now


class Elapsed:
    """Seconds of the supervisor's clock since the start, across new runs (time restarting
    at a restarted simulator counts from there on, never backwards)."""

    def __init__(self, start: float):
        self.total, self.last = 0.0, start

    def __call__(self, now: float) -> float:
        self.total += max(0.0, now - self.last)
        self.last = now
        return self.total


@dataclass(frozen=True)
class SuperviseOptions:
    """What `mrta supervise` watches and how often, built by the verb (or a Python caller)
    and handed to run_supervise. How the snapshots are shown is the caller's."""

    app: str
    once: bool = False
    duration: float | None = None
    sim_time: bool = False
    rate: float = 4.0
    unattended_after: float = 30.0
    duplicate_after: float = 5.0
    ros2_domain: int = 0


def run_supervise(options: SuperviseOptions, bus_options: BusOptions,
                  on_snapshot: Callable[[dict], None],
                  stop: threading.Event | None = None) -> int:
    """Supervise an application on the bus and hand its snapshots to `on_snapshot`: one per
    refresh (`rate` a second) until `duration` or `stop` — on simulated time also once the run
    has ended, when the duration would never pass; with `once`, a single one after the
    monitors' timeouts. The supervisor never prints: the verb shows the snapshots."""
    o = options
    app, arch = resolve_application(o.app)
    with Node(bus_options, OBSERVER, time=NodeTime.SIM if o.sim_time else NodeTime.WALL,
              stop=stop) as node:
        bus, clock, stop = node.bus, node.clock, node.stop
        if not node.wait_for_clock():
            return 0
        sup = Supervisor(arch, app, clock.now(), o.unattended_after, o.duplicate_after,
                         ros2_domain=o.ros2_domain, watch=application_watch(app),
                         serving=serving_of(app.architecture))
        for h in attach(sup, bus, clock):
            node.hold(h)
        wall_start = time.monotonic()
        settle = max([m.topic.timeout for m in sup.monitors] + [1.0])
        refresh = Refresh(sup, clock, o.sim_time)
        elapsed = Elapsed(clock.now())
        while True:
            stop.wait(1.0 / o.rate)
            now = refresh()
            if o.once:  # wall time: a stopped simulation must not hold `--once` forever
                if time.monotonic() - wall_start >= settle or stop.is_set():
                    break
                continue
            if stop.is_set() or (o.duration is not None and elapsed(now) >= o.duration):
                break
            on_snapshot(sup.snapshot(now))
            if o.duration is not None and sup.run_ended:
                break  # the simulated duration will never pass: the run is over
        if o.once:
            on_snapshot(sup.snapshot(clock.now()))
    return 0
