"""`mrta supervise APP`: a thin click wrapper over supervisor.api.run_supervise."""

from __future__ import annotations

import click

from mrta_zenoh.bus import BusOptions
from mrta_zenoh.cli.common import bus_options, finite_float, user_errors

from .api import run_supervise


@click.command()
@click.argument("app")
@click.option("--json", "as_json", is_flag=True, help="One JSON snapshot per line (docs/architecture.md).")
@click.option("--once", is_flag=True, help="One snapshot after the monitors' timeouts, then exit.")
@click.option("--duration", type=finite_float(min=0, min_open=True),
              help="Stop after this many seconds.")
@click.option("--sim-time", is_flag=True, help="Follow the simulator's clock.")
@click.option("--rate", type=click.FloatRange(min=0.5, max=50), default=4.0, show_default=True,
              help="Refreshes (or JSON snapshots) per second.")
@click.option("--unattended-after", type=finite_float(min=0, min_open=True), default=30.0, show_default=True,
              help="Alarm when a task has had no robot for this many seconds.")
@click.option("--duplicate-after", type=finite_float(min=0, min_open=True), default=5.0, show_default=True,
              help="Alarm when two robots do a single-robot task for this many seconds.")
@bus_options
def supervise(app: str, as_json: bool, once: bool, duration: float | None, sim_time: bool,
              rate: float, unattended_after: float, duplicate_after: float,
              bus_options: BusOptions) -> None:
    """Supervise APP (a registered application or its rqt_mrta.xml): robots, tasks, alarms."""
    with user_errors():
        run_supervise(app=app, bus_options=bus_options, as_json=as_json, once=once,
                      duration=duration, sim_time=sim_time, rate=rate,
                      unattended_after=unattended_after, duplicate_after=duplicate_after)
