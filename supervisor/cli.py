"""`mrta supervise APP` and `mrta view`: thin click wrappers over supervisor.api.run_supervise
and supervisor.viewer.run_view. Showing the snapshots (JSON lines, a live table) is done here:
the supervisor itself never prints."""

from __future__ import annotations

from pathlib import Path

import click
from rich.console import Console
from rich.live import Live

from mrta_zenoh.bus import BusOptions
from mrta_zenoh.cli.common import bus_options, finite_float

from .api import SuperviseOptions, run_supervise, to_json
from .view import render


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
@click.option("--ros2-domain", type=click.IntRange(0, 232), default=0, show_default=True,
              envvar="ROS_DOMAIN_ID", help="The ROS 2 domain whose graph is shown (ROS_DOMAIN_ID).")
@bus_options
def supervise(as_json: bool, bus_options: BusOptions, **options) -> None:
    """Supervise APP (a registered application or its rqt_mrta.xml): robots, tasks, alarms,
    and the ROS 2 graph (a robot whose ROS 2 driver node is gone is offline)."""
    opts = SuperviseOptions(**options)  # each option is named as its field
    if as_json:
        run_supervise(opts, bus_options, lambda snap: click.echo(to_json(snap)))
        return
    console = Console()
    if opts.once:
        run_supervise(opts, bus_options, lambda snap: console.print(render(snap, console.width)))
        return
    with LiveTable(console, opts.rate) as table:
        run_supervise(opts, bus_options, table.show)


class LiveTable:
    """The supervisor's table redrawn in place, started with the first snapshot (so that
    nothing is drawn for an application that does not load)."""

    def __init__(self, console: Console, rate: float):
        self.console, self.rate = console, rate
        self.live: Live | None = None

    def show(self, snap: dict) -> None:
        table = render(snap, self.console.width)
        if self.live is None:
            self.live = Live(table, console=self.console, refresh_per_second=self.rate,
                             transient=False)
            self.live.start()
        else:
            self.live.update(table)

    def __enter__(self) -> "LiveTable":
        return self

    def __exit__(self, *exc: object) -> None:
        if self.live is not None:
            self.live.stop()


@click.command()
@click.argument("app", required=False)
@click.option("--port", type=click.IntRange(0, 65535), default=8765, show_default=True,
              help="Foxglove WebSocket port (on --host).")
@click.option("--host", default="127.0.0.1", show_default=True,
              help="Address to serve on (loopback unless you say otherwise).")
@click.option("--no-server", is_flag=True, help="Do not serve: only write --output.")
@click.option("--output", "-o", type=click.Path(dir_okay=False, path_type=Path),
              help="Also record everything (bus, scene, supervisor) to this MCAP file.")
@click.option("--sim-time", is_flag=True, help="Follow the simulator's clock.")
@click.option("--duration", type=finite_float(min=0, min_open=True),
              help="Stop after this many wall seconds.")
@bus_options
def view(app: str | None, port: int, host: str, no_server: bool, output: Path | None,
         sim_time: bool, duration: float | None, bus_options: BusOptions) -> None:
    """Serve APP's robots, scene and supervisor to Foxglove (ws://HOST:PORT), live."""
    from .viewer import run_view

    def ready(url):
        if url:
            click.echo(f"Foxglove / Lichtblick: Open connection → {url}", err=True)
    run_view(app=app, bus_options=bus_options, port=None if no_server else port, host=host,
             output=output, sim_time=sim_time, duration=duration, on_ready=ready)
