"""`mrta demo`: the patrol application end to end, in one command.

It runs the application's own launch file, `patrol_sim.launch` (the simulator and one agent per
robot: ALLIANCE's, or MURDOCH's with `--architecture murdoch`, whose application is the generated
package `patrol_murdoch`), through the runner `mrta launch` uses, plus a recorder, all as separate
processes on a private loopback rendezvous; this process is the supervisor and shows its view.
Readiness is read from liveliness tokens (each robot's agent, the recorder, the clock source),
never from log lines; the simulator itself starts the clock only once every robot is up. It can
SIGKILL one agent mid-mission. Afterwards it writes, into the output folder, the recording, a
world picture with trails, the allocation timeline, the motivation plots and a summary (who did
what, takeover time beside the bound the architecture states for it, mission metrics). The
supervisor, recorder and plots are the same for both architectures; the ALLIANCE-only motivation
panels are simply not produced for MURDOCH (there are no motivation samples to plot).
"""

from __future__ import annotations

import json
import logging
import os
import signal
import threading
import time
from pathlib import Path
from typing import Callable, NamedTuple

from rich.console import Console, Group
from rich.live import Live
from rich.text import Text

from mrta_zenoh import keys
from mrta_zenoh.bus import BusOptions, open_bus
from mrta_zenoh.bus.options import private_rendezvous
from mrta_zenoh.clock import SimClock, follow_sim_clock
from mrta_zenoh.errors import ConfigError, Interrupted, MrtaRuntimeError
from mrta_zenoh.failure import USAGE, Failure, parse_failure
from mrta_zenoh.files import write_text
from mrta_zenoh.lifecycle import stop_on_signals
from mrta_zenoh.presence import RobotPresence
from mrta_zenoh.processes import Child, ProcessGroup, mrta_argv
from mrta_zenoh.recording import read_recording
from mrta_zenoh.toolchain.launchfile import LaunchEvaluator, check_executables
from mrta_zenoh.toolchain.registry import Registry
from mrta_zenoh.toolchain.runner import start_nodes
from mrta_agent.murdoch.api import takeover_bound as murdoch_bound
from mrta_agent.alliance.api import takeover_bound as alliance_bound
from mrta_agent.runtime.host import CRASH_ENV
from mrta_agent.runtime.params import load_layers_params
from mrta_agent.alliance.plots import plot_motivation
from mrta_supervisor.api import Refresh, attach
from mrta_supervisor.plots import TimeBase, allocation_intervals, plot_timeline, replay
from mrta_supervisor.state import Supervisor
from mrta_supervisor.view import render

from .layers import BorderParams
from .metrics import coverage, mission_metrics

log = logging.getLogger("mrta.demo")
LAUNCH = "patrol_sim.launch"
READY_TIMEOUT = 60.0  # wall seconds for every process to come up


class Flavour(NamedTuple):
    """The patrol mission under one architecture: its application package, the stem of its
    parameter files, and the takeover bound the architecture states (with its formula)."""

    application: str
    stem: str
    bound: Callable[[Path, str], float]
    formula: str


ARCHITECTURES = {
    "alliance": Flavour("patrol", "alliance", alliance_bound, "τ + (⌈θ/fast⌉ + 1)/ρ"),
    "murdoch": Flavour("patrol_murdoch", "murdoch", murdoch_bound,
                       "lease + bid window + 3 ticks"),
}


def parse_fail(spec: str | None) -> Failure | None:
    if spec is None or spec.lower() == "none":
        return None
    try:
        return parse_failure(spec)
    except ValueError:
        raise ConfigError(f"--fail {spec!r}: expected {USAGE}, or none") from None


class Readiness:
    """Who is up, from liveliness tokens: the robots (RobotPresence), the recorder and the clock
    source (tokens under @mrta/…, which `**` does not match)."""

    def __init__(self, bus, robots: list[str]):
        self.presence = RobotPresence(bus, robots)
        self.recorder = threading.Event()
        self.clock = threading.Event()
        self._handles = [
            self.presence,
            bus.watch_liveliness(keys.RECORDER_TOKEN + "/**", lambda k, up: up and self.recorder.set()),
            bus.watch_liveliness(keys.CLOCK_SOURCE_TOKEN + "/**", lambda k, up: up and self.clock.set()),
        ]

    def robots_up(self) -> bool:
        return self.presence.all_up()

    def wait(self, what, label: str, group: ProcessGroup, stop: threading.Event) -> None:
        deadline = time.monotonic() + READY_TIMEOUT
        while not what():
            failed = group.failed()
            if failed:
                raise MrtaRuntimeError(f"{failed[0].name} failed while starting:\n{failed[0].tail()}")
            if stop.is_set():
                raise Interrupted()
            if time.monotonic() > deadline:
                raise MrtaRuntimeError(f"{label} did not come up within {READY_TIMEOUT:.0f} s")
            stop.wait(0.05)

    def close(self) -> None:
        for h in self._handles:
            h.close()


def run_demo(*, duration: float = 60.0, speed: float = 2.0, fail: str | None = "robot2@30",
             output: Path = Path("demo-output"), seed: int = 0, live: bool | None = None,
             lockstep: bool = True, foxglove_port: int | None = None,
             architecture: str = "alliance", stop: threading.Event | None = None,
             out=None) -> dict:
    console = Console(file=out) if out is not None else Console()
    failure = parse_fail(fail)
    flavour = ARCHITECTURES.get(architecture)
    if flavour is None:
        raise ConfigError(f"--architecture {architecture!r}: expected one of "
                          f"{', '.join(ARCHITECTURES)}")
    reg = Registry()
    pkg, app = reg.application(flavour.application)
    _, arch = reg.architecture(app.architecture)
    ids = [r.id for r in app.robots]
    if failure and failure.robot not in ids:
        raise ConfigError(f"--fail {fail}: {failure.robot} is not one of {', '.join(ids)}")
    if failure and failure.at >= duration:
        raise ConfigError(f"--fail at {failure.at} s is not before the end ({duration} s)")
    output.mkdir(parents=True, exist_ok=True)
    config = pkg.path / "config"
    params = {rid: config / f"{rid}_{flavour.stem}_params.yaml" for rid in ids}
    layers = load_layers_params(config / f"layers_{flavour.stem}_params.yaml")
    border = layers.convert(("BorderProtection",), BorderParams)
    launch_args = {"speed": str(speed), "seed": str(seed),
                   "sim_args": f"--duration {duration} --snapshot {output / 'world.png'}"
                               + (" --lockstep" if lockstep else "")}
    nodes = LaunchEvaluator(lambda name: reg.find(name).path).run(pkg.path / "launch" / LAUNCH,
                                                                 launch_args)
    check_executables(nodes)
    rendezvous = private_rendezvous()
    env = dict(os.environ, MRTA_RENDEZVOUS=rendezvous, PYTHONUNBUFFERED="1")
    if lockstep and failure:
        # the agent crashes itself at that simulated time: exact, so a run replays exactly
        env[CRASH_ENV] = failure.spec
    failed_at: float | None = None
    t_wall0 = time.monotonic()
    with stop_on_signals(stop) as stop, ProcessGroup(env) as group, \
            open_bus(BusOptions(rendezvous=rendezvous)) as bus:
        ready = Readiness(bus, ids)
        # the recording: the bus, the scene and the supervisor's channels, readable by Foxglove;
        # with --foxglove the same channels are also served live
        view = ["view", flavour.application, "--sim-time", "--output", output / "run.mcap"]
        view += ["--port", str(foxglove_port)] if foxglove_port is not None else ["--no-server"]
        group.start(mrta_argv(*view), name="record")
        ready.wait(ready.recorder.is_set, "the recorder", group, stop)
        if foxglove_port is not None:
            console.print(f"Foxglove / Lichtblick: Open connection → ws://127.0.0.1:{foxglove_port}",
                          highlight=False)
        clock = SimClock()
        clock_handles = follow_sim_clock(bus, clock)
        sup = Supervisor(arch, app, 0.0, unattended_after=30.0, duplicate_after=5.0)
        handles = attach(sup, bus, clock)
        children = start_nodes(group, nodes)
        agents = {rid: next(c for c in children if c.name.startswith(rid + "/")) for rid in ids}
        sim = next(c for c in children if c not in agents.values())
        ready.wait(ready.robots_up, "the robots' agents", group, stop)
        ready.wait(ready.clock.is_set, "the simulator", group, stop)
        show_live = console.is_terminal if live is None else live
        failed_at = _run(sim, sup, clock, agents, failure, duration, speed, stop, console,
                         show_live, kill=not lockstep, title=f"patrol ({arch.name})")
        for h in handles + clock_handles:
            h.close()
        ready.close()
        if stop.is_set() and sim.running():
            raise Interrupted()
        if sim.wait(30) != 0:
            raise MrtaRuntimeError("the simulator failed:\n" + sim.tail())
        group.stop_all()
        crashed = group.failed(ignore=[agents[failure.robot].name] if failure else [])
        if crashed:
            raise MrtaRuntimeError(f"{', '.join(c.name for c in crashed)} exited with an error:\n"
                                   + "\n".join(c.tail(5) for c in crashed))
    summary = analyse(output, app, arch, ids, params, border, failure, failed_at, duration,
                      speed, time.monotonic() - t_wall0, flavour)
    print_summary(console, summary)
    return summary


def _run(sim: Child, sup: Supervisor, clock: SimClock, agents: dict[str, Child], failure,
         duration: float,
         speed: float, stop: threading.Event, console: Console, show_live: bool, kill: bool = True,
         title: str = "patrol") -> float | None:
    failed_at = None
    last_line = -10.0

    def header() -> Text:
        t = clock.now()
        fail_txt = "" if not failure else (f" · {failure.robot} killed at {failed_at:.1f} s"
                                           if failed_at is not None
                                           else f" · will kill {failure.robot} at {failure.at:.0f} s")
        return Text(f"mrta demo · {title} · simulated {t:5.1f} / {duration:.0f} s · "
                    f"speed {speed or 'max'}{fail_txt}", style="bold")

    live = Live(Group(header(), render(sup.snapshot(clock.now()), console.width)), console=console,
                refresh_per_second=4, transient=False) if show_live else None
    if live:
        live.start()
    refresh = Refresh(sup, clock, sim_time=True)
    try:
        while sim.running() and not stop.is_set():
            stop.wait(0.25)
            now = refresh()
            if failure and failed_at is None and now >= failure.at:
                if kill:  # otherwise the agent crashed itself at exactly failure.at
                    agents[failure.robot].signal(signal.SIGKILL)
                failed_at = now if kill else failure.at
                log.info("killed %s at %.1f s", failure.robot, failed_at)
            if live:
                live.update(Group(header(), render(sup.snapshot(now), console.width)))
            elif now - last_line >= 10.0:
                last_line = now
                snap = sup.snapshot(now)
                console.print(f"t={now:5.1f}s  " + "  ".join(
                    f"{r['id']}:{r['state']}{'/' + r['task'] if r['task'] else ''}"
                    for r in snap["robots"]), highlight=False)
    finally:
        if live:
            live.stop()
    return failed_at


def analyse(output: Path, app, arch, ids, params, border: BorderParams, failure, failed_at,
            duration: float, speed: float, wall: float,
            flavour: Flavour = ARCHITECTURES["alliance"]) -> dict:
    records = read_recording(output / "run.mcap")
    tb = TimeBase(records)
    sup = replay(records, tb, app, arch)
    t0 = 0.0
    t1 = max((tb(t) for _, _, t, _ in records), default=duration)
    intervals = allocation_intervals(sup, t1)
    plot_timeline(output / "run.mcap", app, arch, output / "timeline.png", records, sup)
    plots = []
    for rid in ids:
        for task in app.tasks():
            f = output / f"motivation_{rid}_{task}.png"
            try:
                plot_motivation(output / "run.mcap", rid, task, f, records)
                plots.append(f.name)
            except ConfigError:
                pass  # a robot killed before its first sample of this task
    who = {rid: [{"task": t, "from": round(a, 1), "to": round(b, 1)}
                 for t, a, b in sorted(intervals.get(rid, []), key=lambda x: x[1])] for rid in ids}
    summary = {"architecture": arch.name, "application": flavour.application,
               "duration": duration, "speed": speed, "wall_seconds": round(wall, 1),
               "robots": ids, "who_did_what": who,
               "first_full_allocation": first_full_allocation(intervals, app.tasks()),
               "coverage": coverage(intervals, app.tasks(), t0, t1),
               "output": str(output), "files": sorted(p.name for p in output.iterdir())}
    summary.update(mission_metrics(records, border.border() or (-20.0, -6.0, 20.0, 6.0),
                                   border.distance + 1.0))
    summary["messages"] = message_rates(records, arch, max(t1 - t0, 1e-9))
    if failure:
        robot = failure.robot
        summary["failure"] = {"robot": robot, "killed_at": failed_at}
        if failed_at is not None:
            task = next((t for t, a, b in intervals.get(robot, []) if a <= failed_at <= b + 0.5),
                        None)
            taken = sorted((a, r) for r, iv in intervals.items() if r != robot
                           for t, a, b in iv if t == task and a >= failed_at - 1e-6) if task else []
            summary["failure"]["task"] = task
            if taken:
                t_take, by = taken[0]
                summary["failure"].update({
                    "taken_over_by": by, "takeover_seconds": round(t_take - failed_at, 2),
                    "bound_seconds": round(flavour.bound(params[by], task), 2),
                    "bound_formula": flavour.formula})
    write_text(output / "summary.json", json.dumps(summary, indent=2))
    return summary


def message_rates(records, arch, seconds: float) -> dict:
    """Samples per simulated second on the bus (liveliness events aside), and the share the
    architecture's own coordination takes: keys under its namespace — the second chunk of its
    busy-robots topic (`*/alliance/…`, `*/murdoch/…`), read from the architecture file."""
    topic = arch.busy_robots.name if arch.busy_robots else ""
    parts = topic.strip("/").split("/")
    namespace = parts[1] if len(parts) > 1 else None
    total = coordination = 0
    for key, _, _, _ in records:
        if key.startswith("@"):
            continue
        total += 1
        chunks = key.split("/")
        if namespace is not None and len(chunks) > 1 and chunks[1] == namespace:
            coordination += 1
    return {"total_per_second": round(total / seconds, 1),
            "coordination_per_second": round(coordination / seconds, 1),
            "coordination_namespace": namespace}


def first_full_allocation(intervals: dict, tasks) -> float | None:
    """The first time every task was held by some robot (None: never during the run)."""
    events = sorted({a for iv in intervals.values() for _, a, _ in iv})
    for t in events:
        held = {task for iv in intervals.values() for task, a, b in iv if a <= t <= b}
        if set(tasks) <= held:
            return round(t, 2)
    return None


def print_summary(console: Console, s: dict) -> None:
    console.print(Text(f"\nPatrol mission ({s['architecture']}): {s['duration']:.0f} s simulated at speed "
                       f"{s['speed'] or 'max'} in {s['wall_seconds']:.0f} s", style="bold"))
    for rid, spans in s["who_did_what"].items():
        txt = ", ".join(f"{x['task']} {x['from']:.1f}–{x['to']:.1f} s" for x in spans) or "idle"
        console.print(f"  {rid}: {txt}", highlight=False)
    f = s.get("failure")
    if f:
        if "takeover_seconds" in f:
            ok = "within" if f["takeover_seconds"] <= f["bound_seconds"] else "OVER"
            console.print(f"  {f['robot']} killed at {f['killed_at']:.1f} s while doing {f['task']}; "
                          f"{f['taken_over_by']} took over after {f['takeover_seconds']:.2f} s "
                          f"({ok} the bound {f['bound_formula']} = {f['bound_seconds']:.2f} s)",
                          highlight=False)
        else:
            console.print(f"  {f['robot']} killed at {f.get('killed_at')}; task "
                          f"{f.get('task')} was not taken over before the end", highlight=False)
    for task, c in s["coverage"].items():
        console.print(f"  {task}: exactly one robot {c['exactly_one']:.0%}, none {c['none']:.0%}, "
                      f"more than one {c['more_than_one']:.0%}", highlight=False)
    console.print(f"  collisions: {s['collisions_total']}; border visited: "
                  f"{s['border_visited']:.0%}", highlight=False)
    console.print(f"  files in {s['output']}: {', '.join(s['files'])}", highlight=False)
