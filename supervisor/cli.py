"""`mrta supervise APP`: watch an application's robots and tasks live, as JSON, or once."""

from __future__ import annotations

import json
import logging
import threading
from collections import defaultdict
from pathlib import Path

import click
from rich.console import Console
from rich.live import Live

from mrta_zenoh import keys
from mrta_zenoh.bus import Bus, BusOptions, open_bus
from mrta_zenoh.cli.common import bus_options, user_errors
from mrta_zenoh.clock import SimClock, WallClock
from mrta_zenoh.errors import ConfigError
from mrta_zenoh.lifecycle import stop_on_signals
from mrta_zenoh.messages import Clock as ClockMsg
from mrta_zenoh.toolchain.model import Application, Architecture
from mrta_zenoh.toolchain.registry import Registry
from mrta_zenoh.toolchain.xmlio import load_rqt_mrta

from .state import Supervisor
from .view import render

log = logging.getLogger("mrta.supervisor")


def resolve_application(spec: str, registry: Registry | None = None) -> tuple[Application, Architecture]:
    """An application by name (registry) or by path, and the architecture it names."""
    reg = registry or Registry()
    path = Path(spec)
    if path.is_dir():
        path = path / "rqt_mrta.xml"
    if path.suffix == ".xml" and path.is_file():
        app = load_rqt_mrta(path)
        if not isinstance(app, Application):
            raise ConfigError("not an application file", file=str(path))
    else:
        _, app = reg.application(spec)
    _, arch = reg.architecture(app.architecture)
    return app, arch


def attach(sup: Supervisor, bus: Bus, clock) -> list:
    """Subscribe once per key expression for the monitors that read it, and watch liveliness."""
    by_key = defaultdict(list)
    for m in sup.monitors:
        by_key[m.key_expr].append(m)
    handles = []
    for key_expr, monitors in by_key.items():
        def handler(sample, monitors=monitors):
            sup.on_sample(monitors, sample.key, sample.type_name, sample.message, clock.now())
        handles.append(bus.subscribe(key_expr, handler))
    handles.append(bus.watch_liveliness("**", lambda k, alive: sup.on_liveliness(k, alive,
                                                                                clock.now())))
    return handles


def main(app_spec: str, bus_opts: BusOptions, as_json: bool = False, once: bool = False,
         duration: float | None = None, sim_time: bool = False, rate: float = 4.0,
         unattended_after: float = 30.0, duplicate_after: float = 5.0,
         stop: threading.Event | None = None, out=None) -> int:
    with user_errors():
        app, arch = resolve_application(app_spec)
    clock = SimClock() if sim_time else WallClock()
    console = Console(file=out) if out is not None else Console()
    with user_errors(), stop_on_signals(stop) as stop, open_bus(bus_opts) as bus:
        if sim_time:
            bus.subscribe(keys.CLOCK, lambda s: clock.on_clock(s.message.stamp), msg_type=ClockMsg)
            while not clock.started.wait(0.1):
                if stop.is_set():
                    return 0
        sup = Supervisor(arch, app, clock.now(), unattended_after, duplicate_after)
        handles = attach(sup, bus, clock)
        start = clock.now()
        settle = max([m.topic.timeout for m in sup.monitors] + [1.0])
        period = 1.0 / rate

        def done() -> bool:
            now = clock.now()
            if once:
                return now - start >= settle
            return stop.is_set() or (duration is not None and now - start >= duration)

        def wait() -> None:
            target = clock.now() + period
            if sim_time:
                clock.sleep_until(target, stop)
            else:
                stop.wait(period)

        try:
            if as_json or once:
                while True:
                    wait()
                    sup.update(clock.now())
                    if done() or stop.is_set():
                        break
                    if as_json and not once:
                        print(json.dumps(sup.snapshot(clock.now())), flush=True, file=out)
                snap = sup.snapshot(clock.now())
                if once:
                    if as_json:
                        print(json.dumps(snap), flush=True, file=out)
                    else:
                        console.print(render(snap))
            else:
                with Live(render(sup.snapshot(clock.now())), console=console,
                          refresh_per_second=rate, transient=False) as live:
                    while not done():
                        wait()
                        sup.update(clock.now())
                        live.update(render(sup.snapshot(clock.now())))
        finally:
            for h in handles:
                h.close()
    return 0


@click.command()
@click.argument("app")
@click.option("--json", "as_json", is_flag=True, help="One JSON snapshot per line (DESIGN §9).")
@click.option("--once", is_flag=True, help="One snapshot after the monitors' timeouts, then exit.")
@click.option("--duration", type=float, help="Stop after this many seconds.")
@click.option("--sim-time", is_flag=True, help="Follow the simulator's clock.")
@click.option("--rate", type=click.FloatRange(min=0.5, max=50), default=4.0, show_default=True,
              help="Refreshes (or JSON snapshots) per second.")
@click.option("--unattended-after", type=float, default=30.0, show_default=True,
              help="Alarm when a task has had no robot for this many seconds.")
@click.option("--duplicate-after", type=float, default=5.0, show_default=True,
              help="Alarm when two robots do a single-robot task for this many seconds.")
@bus_options
def supervise(app: str, as_json: bool, once: bool, duration: float | None, sim_time: bool,
              rate: float, unattended_after: float, duplicate_after: float,
              bus_options: BusOptions) -> None:
    """Supervise APP (a registered application or its rqt_mrta.xml): robots, tasks, alarms."""
    if not logging.getLogger().handlers:
        logging.basicConfig(format="%(levelname)s %(name)s: %(message)s")
    main(app, bus_options, as_json, once, duration, sim_time, rate, unattended_after,
         duplicate_after)
