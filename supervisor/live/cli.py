"""`mrta supervise APP` and `mrta view`: thin click wrappers over supervisor.api.run_supervise
and supervisor.viewer.run_view. Showing the snapshots (JSON lines, a live table) is done here:
the supervisor itself never prints.

Times people read are relative: simulated seconds with `--sim-time`, otherwise seconds since
`mrta supervise` started (the supervisor's own clock is then the Unix epoch, 1795480671.6,
which nobody reads at a glance). A `--json` line keeps the supervisor's clock in `time` and
every `since` (so they compare with each other), and adds `wall_time` (Unix epoch seconds when
the snapshot was taken) and `sim_time` (simulated seconds, or null without `--sim-time`).
Into a pipe (no terminal) the live table becomes one line per change, written at once. The
views name the alarms themselves, so the supervisor's alarm log lines are off while they run
(with `--json` they stay on stderr, beside the snapshots on stdout)."""

from __future__ import annotations

import contextlib
import logging
import time
from pathlib import Path

import click
from rich.console import Console, Group
from rich.live import Live
from rich.text import Text

from mrta_zenoh.bus import BusOptions
from mrta_zenoh.cli.common import bus_options, finite_float
from mrta_zenoh.cli.common import console as make_console
from mrta_zenoh.lifecycle import Closing
from mrta_zenoh.untrusted import visible

from .alarms import ALARM_LOG
from .api import SuperviseOptions, run_supervise, to_json
from .view import render


@contextlib.contextmanager
def quiet_alarms():
    """The supervisor's alarm log lines off while a view that names the alarms runs."""
    alarms = logging.getLogger(ALARM_LOG)
    level = alarms.level
    alarms.setLevel(logging.ERROR)
    try:
        yield
    finally:
        alarms.setLevel(level)


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
    if as_json:  # click.echo flushes: a pipe gets each line as it is made
        run_supervise(opts, bus_options,
                      lambda snap: click.echo(to_json(with_clocks(snap, opts.sim_time))))
        return
    console = make_console()
    origin = 0.0 if opts.sim_time else time.time()
    if opts.once:
        run_supervise(opts, bus_options, lambda snap: console.print(
            render(relative(snap, origin), console.width)))
        return
    if not console.is_terminal:
        with quiet_alarms():  # the lines name the alarms
            run_supervise(opts, bus_options, ChangeLines(console, origin))
        return
    with LiveScreen(console) as screen:
        run_supervise(opts, bus_options,
                      lambda snap: screen.show(render(relative(snap, origin), console.width)))


def with_clocks(snap: dict, sim_time: bool) -> dict:
    """The snapshot with `wall_time` and `sim_time` beside `time` (the supervisor's clock)."""
    return {"time": snap["time"], "wall_time": round(time.time(), 3),
            "sim_time": snap["time"] if sim_time else None,
            **{k: v for k, v in snap.items() if k != "time"}}


def relative(snap: dict, origin: float) -> dict:
    """The snapshot with every time counted from `origin` (the start of supervision)."""
    if not origin:
        return snap

    def shift(t):
        return None if t is None else t - origin

    out = dict(snap, time=shift(snap["time"]))
    out["robots"] = [dict(r, since=shift(r["since"])) for r in snap["robots"]]
    out["tasks"] = [dict(t, since=shift(t["since"])) for t in snap["tasks"]]
    out["alarms"] = [dict(a, since=shift(a["since"])) for a in snap["alarms"]]
    out["transitions"] = [dict(tr, time=shift(tr["time"])) for tr in snap["transitions"]]
    return out


def state_line(snap: dict) -> str:
    """Robots, tasks held and alarms in one line, for logs and pipes (ids escaped)."""
    robots = "  ".join([f"{r['id']}:{r['state']}" + (f"/{r['task']}" if r["task"] else "")
                        for r in snap["robots"]]
                       + [f"{p['id']}:{'online' if p['online'] else 'offline'}"
                          for p in snap.get("processes", ())])
    alarms = ", ".join(f"{a['kind']} {a['subject']}" for a in snap["alarms"])
    return visible(robots + (f"  alarms: {alarms}" if alarms else ""))


class ChangeLines:
    """Without a terminal: a `t=…` line whenever the robots' states, their tasks or the alarms
    change (a redrawn table means nothing in a file)."""

    def __init__(self, console: Console, origin: float):
        self.console, self.origin, self.last = console, origin, None

    def __call__(self, snap: dict) -> None:
        line = state_line(snap)
        if line != self.last:
            self.last = line
            self.console.print(f"t={snap['time'] - self.origin:7.1f}s  {line}", markup=False,
                               highlight=False)


class LiveScreen(Closing):
    """The live view on a terminal, drawn whole on the alternate screen at each refresh, as
    `top` does: a resized terminal or a view that grows or narrows leaves nothing stale (drawn
    in place, rich moves the cursor up by the height it last drew, which a terminal that
    rewrapped the old lines, or any line written meanwhile, makes wrong — stale headers would
    pile up). Once it is gone its last picture is printed, as an in-place view would have left it.
    Log lines written while it shows would land across it, so they are held and shown in
    the view's last lines instead, then written out in full once it is gone; the
    supervisor's own alarm lines are not written at all — the view shows the alarms.
    The screen is taken at the first frame, so that nothing is drawn for an application that
    does not load; log lines are held, and alarm lines off, from the start."""

    KEEP = 3  # log lines shown under the view

    def __init__(self, console: Console):
        self.console = console
        self.live: Live | None = None
        self.last = None
        self.held: list[str] = []
        self._stack = contextlib.ExitStack()
        self._stack.enter_context(quiet_alarms())
        self._stack.enter_context(_Hold(self.held))

    def show(self, renderable) -> None:
        if self.live is None:
            self.live = Live(console=self.console, screen=True, auto_refresh=False,
                             redirect_stdout=False, redirect_stderr=False)
            self.live.start()
        logs = [Text(visible(line), style="dim") for line in self.held[-self.KEEP:]]
        self.last = renderable
        self.live.update(Group(renderable, *logs), refresh=True)

    def close(self) -> None:
        if self.live is not None:
            self.live.stop()
            self.live = None
            self.console.print(self.last)  # the last picture stays on the terminal
        self._stack.close()
        for line in self.held:
            self.console.print(Text(line), highlight=False, markup=False)
        self.held.clear()


class _Hold(logging.Filter):
    """While entered, a filter on the root's handlers that holds their records (formatted as
    the first of them would have written them) instead of letting them write."""

    def __init__(self, held: list[str]):
        super().__init__()
        self.held = held
        self._handlers: list[logging.Handler] = []
        self._last: logging.LogRecord | None = None

    def __enter__(self) -> "_Hold":
        self._handlers = list(logging.getLogger().handlers)
        for h in self._handlers:
            h.addFilter(self)
        return self

    def __exit__(self, *exc: object) -> None:
        for h in self._handlers:
            h.removeFilter(self)
        self._handlers = []

    def filter(self, record: logging.LogRecord) -> bool:
        if record is not self._last:  # one record reaches every handler: held once
            self._last = record
            self.held.append(self._handlers[0].format(record))
        return False


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
@click.option("--dated", is_flag=True,
              help="With --sim-time: log times start at the wall-clock time the run's clock "
                   "was first heard, so viewers show the run's date; durations stay simulated.")
@click.option("--duration", type=finite_float(min=0, min_open=True),
              help="Stop after this many wall seconds.")
@bus_options
def view(app: str | None, port: int, host: str, no_server: bool, output: Path | None,
         sim_time: bool, dated: bool, duration: float | None, bus_options: BusOptions) -> None:
    """Serve APP's robots, scene and supervisor to Foxglove (ws://HOST:PORT), live."""
    from .viewer import ViewOptions, run_view

    def ready(url):
        if url:
            click.echo(f"Foxglove / Lichtblick: Open connection → {url}", err=True)
    run_view(ViewOptions(app=app, port=None if no_server else port, host=host, output=output,
                         sim_time=sim_time, dated=dated, duration=duration),
             bus_options, on_ready=ready)
