"""`mrta demo`: the patrol application end to end, in one command.

Starts, as separate processes on a private loopback rendezvous: a recorder, one `mrta agent` per
robot (on simulation time), and the simulator; this process is the supervisor and shows its view.
Optionally SIGKILLs one agent mid-mission. Afterwards it writes, into the output folder, the
recording, a world picture with trails, the allocation timeline, the motivation plots and a
summary (who did what, takeover time beside its bound, mission metrics).

This is the patrol application's runner, so it is the one place in this package that reads the
ALLIANCE parameter layout — only to state the takeover bound τ + ⌈θ/fast⌉/spin + 1 it measures
against. The monitoring itself is the generic Supervisor.
"""

from __future__ import annotations

import json
import logging
import math
import os
import signal
import subprocess
import sys
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path

import click
import yaml
from rich.console import Console, Group
from rich.live import Live
from rich.text import Text

from mrta_zenoh import keys
from mrta_zenoh.bus import BusOptions, open_bus
from mrta_zenoh.bus.options import private_rendezvous
from mrta_zenoh.cli.common import BadInput, RuntimeFailure, user_errors
from mrta_zenoh.clock import SimClock
from mrta_zenoh.codec import DecodeError, decode, type_from_encoding
from mrta_zenoh.errors import ConfigError, MrtaRuntimeError
from mrta_zenoh.geometry import rectangle_cells
from mrta_zenoh.lifecycle import stop_on_signals
from mrta_zenoh.messages import Clock as ClockMsg
from mrta_zenoh.toolchain.model import RobotEntry
from mrta_zenoh.toolchain.registry import Registry

from .cli import attach
from .plots import TimeBase, allocation_intervals, plot_motivation, plot_timeline, \
    read_recording, replay
from .state import Supervisor
from .view import render

log = logging.getLogger("mrta.demo")
MAX_ROBOTS = 5  # start poses in the patrol world


@dataclass
class Child:
    name: str
    proc: subprocess.Popen
    lines: list[str] = field(default_factory=list)

    def pump(self) -> None:
        for line in self.proc.stderr:
            self.lines.append(line.rstrip())

    def wait_for(self, text: str, timeout: float) -> None:
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            if any(text in line for line in self.lines):
                return
            if self.proc.poll() is not None:
                break
            time.sleep(0.05)
        raise MrtaRuntimeError(f"{self.name} did not start ({text!r} not seen); its last output:\n"
                               + "\n".join(self.lines[-10:]))


def _spawn(name: str, args: list[str], env: dict) -> Child:
    proc = subprocess.Popen([sys.executable, "-m", "mrta_zenoh.cli.main", *args], env=env,
                            stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL,
                            stderr=subprocess.PIPE, text=True)
    child = Child(name, proc)
    threading.Thread(target=child.pump, daemon=True).start()
    return child


def parse_fail(spec: str | None) -> tuple[str, float] | None:
    if spec is None or spec.lower() == "none":
        return None
    robot, sep, when = spec.partition("@")
    try:
        t = float(when)
        if not sep or t <= 0 or not math.isfinite(t):
            raise ValueError
        return keys.normalize_robot_id(robot), t
    except (ValueError, keys.KeyError_):
        raise BadInput(f"--fail {spec!r}: expected ROBOT@SECONDS, e.g. robot2@30, or none") from None


def takeover_bound(robot_params: Path, task: str) -> float:
    """τ + ⌈θ / fast_rate⌉ / spin_rate + 1 s for `task` in this robot's parameter file."""
    data = yaml.safe_load(robot_params.read_text())
    sets = data["behaviour_sets"]
    for i in range(int(sets["size"])):
        bs = sets[f"behaviour_set{i}"]
        if bs["task_id"] == task:
            mb = bs["motivational_behaviour"]
            ticks = math.ceil(float(mb["threshold"]) / float(mb["impatience"]["fast_rate"]))
            return float(data["timeout_duration"]) + ticks / float(data["spin_rate"]) + 1.0
    raise ConfigError(f"{robot_params} has no behaviour set for {task!r}")


def coverage(intervals: dict, tasks: list[str], t0: float, t1: float, step: float = 0.1) -> dict:
    """Per task: share of [t0, t1] with exactly one robot on it, none, more than one."""
    out = {}
    n = max(1, int((t1 - t0) / step))
    for task in tasks:
        spans = [(a, b) for iv in intervals.values() for tk, a, b in iv if tk == task]
        one = none = many = 0
        for k in range(n):
            t = t0 + (k + 0.5) * step
            c = sum(1 for a, b in spans if a <= t < b)
            one += c == 1
            none += c == 0
            many += c > 1
        out[task] = {"exactly_one": round(one / n, 3), "none": round(none / n, 3),
                     "more_than_one": round(many / n, 3)}
    return out


def mission_metrics(records, tb: TimeBase, border: dict) -> dict:
    """Collisions (from the simulator's bumper counters) and the share of the border visited."""
    collisions: dict[str, int] = {}
    x0, y0, x1, y1 = (float(border[k]) for k in ("x_min", "y_min", "x_max", "y_max"))
    cells = rectangle_cells(x0, y0, x1, y1, 0.5)
    visited = [False] * len(cells)
    reach = float(border.get("distance", 1.0)) + 1.0
    for key, enc, _t, payload in records:
        robot, _, topic = key.partition("/")
        if topic not in ("bumper", "ground_truth"):
            continue
        try:
            msg = decode(type_from_encoding(enc), payload)
        except DecodeError:
            continue
        if topic == "bumper":
            collisions[robot] = max(collisions.get(robot, 0), msg.collisions)
        else:
            px, py = msg.pose.x, msg.pose.y
            for i, (cx, cy) in enumerate(cells):
                if not visited[i] and abs(cx - px) <= reach and abs(cy - py) <= reach \
                        and math.hypot(cx - px, cy - py) <= reach:
                    visited[i] = True
    return {"collisions": collisions, "collisions_total": sum(collisions.values()),
            "border_visited": round(sum(visited) / len(cells), 3) if cells else 0.0}


def main(duration: float = 60.0, speed: float = 2.0, fail: str | None = "robot2@30",
         robots: int = 3, output: Path = Path("demo-output"), seed: int = 0,
         live: bool | None = None, stop: threading.Event | None = None, out=None) -> dict:
    console = Console(file=out) if out is not None else Console()
    with user_errors():
        if not 1 <= robots <= MAX_ROBOTS:
            raise BadInput(f"--robots must be 1–{MAX_ROBOTS} (the patrol world's start poses)")
        if duration <= 0 or speed < 0:
            raise BadInput("--duration must be positive and --speed ≥ 0")
        failure = parse_fail(fail)
        ids = [f"robot{i}" for i in range(1, robots + 1)]
        if failure and failure[0] not in ids:
            raise BadInput(f"--fail {fail}: {failure[0]} is not one of {', '.join(ids)}")
        if failure and failure[1] >= duration:
            raise BadInput(f"--fail at {failure[1]} s is not before the end ({duration} s)")
        reg = Registry()
        pkg, app = reg.application("patrol")
        _, arch = reg.architecture(app.architecture)
        config = pkg.path / "config"
        params = {rid: config / f"robot{(i % 3) + 1}_alliance_params.yaml"
                  for i, rid in enumerate(ids)}
        tasks_file, layers_file = config / "tasks_alliance_params.yaml", \
            config / "layers_alliance_params.yaml"
        output.mkdir(parents=True, exist_ok=True)
    # the application lists 3 robots; a demo with more runs them under the same monitors
    app.robots = [RobotEntry(rid, app.tasks()) for rid in ids]
    rendezvous = private_rendezvous()
    os.environ["MRTA_RENDEZVOUS"] = rendezvous  # our own bus joins the private rendezvous too
    env = dict(os.environ, MRTA_RENDEZVOUS=rendezvous, PYTHONUNBUFFERED="1")
    children: list[Child] = []
    agents: dict[str, Child] = {}
    failed_at: float | None = None
    t_wall0 = time.monotonic()
    try:
        with stop_on_signals(stop) as stop:
            rec = _spawn("record", ["record", "-o", str(output / "run.mcap")], env)
            children.append(rec)
            rec.wait_for("recording", 30)
            for rid in ids:
                a = _spawn(rid, ["agent", rid, "--robot-params", str(params[rid]),
                                 "--tasks-params", str(tasks_file), "--layers-params",
                                 str(layers_file), "--sim-time", "--seed", str(seed)], env)
                agents[rid] = a
                children.append(a)
            for a in agents.values():
                a.wait_for("ready", 60)
            clock = SimClock()
            with open_bus(BusOptions()) as bus:
                bus.subscribe(keys.CLOCK, lambda s: clock.on_clock(s.message.stamp),
                              msg_type=ClockMsg)
                sup = Supervisor(arch, app, 0.0, unattended_after=30.0, duplicate_after=5.0)
                handles = attach(sup, bus, clock)
                sim = _spawn("sim", ["sim", "--world", "patrol", *sum((["--robot", r] for r in ids), []),
                                     "--speed", str(speed), "--seed", str(seed),
                                     "--duration", str(duration),
                                     "--snapshot", str(output / "world.png")], env)
                children.append(sim)
                show_live = console.is_terminal if live is None else live
                failed_at = _run(sim, sup, clock, agents, failure, duration, speed, stop, console,
                                 show_live)
                for h in handles:
                    h.close()
                if stop.is_set() and sim.proc.poll() is None:
                    raise click.Abort()
                if sim.proc.wait(30) != 0:
                    raise MrtaRuntimeError("the simulator failed:\n" + "\n".join(sim.lines[-10:]))
    finally:
        for c in reversed(children):
            if c.proc.poll() is None:
                c.proc.send_signal(signal.SIGINT)
        for c in reversed(children):
            try:
                c.proc.wait(15)
            except subprocess.TimeoutExpired:
                c.proc.kill()
                c.proc.wait()
    crashed = [c.name for c in children if c.proc.returncode not in (0, -signal.SIGKILL)
               and not (failure and c.name == failure[0])]
    if crashed:
        raise MrtaRuntimeError(f"{', '.join(crashed)} exited with an error:\n"
                               + "\n".join(line for c in children if c.name in crashed
                                           for line in c.lines[-5:]))
    summary = analyse(output, app, arch, ids, params, layers_file, failure, failed_at, duration,
                      speed, time.monotonic() - t_wall0)
    print_summary(console, summary)
    return summary


def _run(sim: Child, sup: Supervisor, clock: SimClock, agents: dict, failure, duration: float,
         speed: float, stop: threading.Event, console: Console, show_live: bool) -> float | None:
    failed_at = None
    last_line = -10.0

    def header() -> Text:
        t = clock.now()
        fail_txt = "" if not failure else (f" · {failure[0]} killed at {failed_at:.1f} s"
                                           if failed_at is not None
                                           else f" · will kill {failure[0]} at {failure[1]:.0f} s")
        return Text(f"mrta demo · patrol · simulated {t:5.1f} / {duration:.0f} s · "
                    f"speed {speed or 'max'}{fail_txt}", style="bold")

    live = Live(Group(header(), render(sup.snapshot(clock.now()))), console=console,
                refresh_per_second=4, transient=False) if show_live else None
    if live:
        live.start()
    try:
        while sim.proc.poll() is None and not stop.is_set():
            stop.wait(0.25)
            now = clock.now()
            sup.update(now)
            if failure and failed_at is None and now >= failure[1]:
                agents[failure[0]].proc.send_signal(signal.SIGKILL)
                failed_at = now
                log.info("killed %s at %.1f s", failure[0], now)
            if live:
                live.update(Group(header(), render(sup.snapshot(now))))
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


def analyse(output: Path, app, arch, ids, params, layers_file: Path, failure, failed_at,
            duration: float, speed: float, wall: float) -> dict:
    records = list(read_recording(output / "run.mcap"))
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
    summary = {"duration": duration, "speed": speed, "wall_seconds": round(wall, 1),
               "robots": ids, "who_did_what": who,
               "coverage": coverage(intervals, app.tasks(), t0, t1),
               "output": str(output), "files": sorted(p.name for p in output.iterdir())}
    layers = yaml.safe_load(layers_file.read_text()) or {}
    summary.update(mission_metrics(records, tb, layers.get("BorderProtection") or
                                   {"x_min": -20, "y_min": -6, "x_max": 20, "y_max": 6}))
    if failure:
        robot, _ = failure
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
                    "bound_seconds": round(takeover_bound(params[by], task), 2)})
    (output / "summary.json").write_text(json.dumps(summary, indent=2))
    return summary


def print_summary(console: Console, s: dict) -> None:
    console.print(Text(f"\nPatrol mission: {s['duration']:.0f} s simulated at speed "
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
                          f"({ok} the bound τ + ⌈θ/fast⌉/ρ + 1 = {f['bound_seconds']:.2f} s)",
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


@click.command()
@click.option("--duration", type=float, default=60.0, show_default=True,
              help="Simulated seconds of mission.")
@click.option("--speed", type=float, default=2.0, show_default=True,
              help="Simulated seconds per wall second (0: as fast as possible).")
@click.option("--fail", default="robot2@30", show_default=True, metavar="ROBOT@SECONDS|none",
              help="SIGKILL this robot's agent at this simulated time.")
@click.option("--robots", type=int, default=3, show_default=True, help="How many robots (1–5).")
@click.option("--output", type=click.Path(file_okay=False, path_type=Path),
              default=Path("demo-output"), show_default=True,
              help="Folder for the recording, pictures and summary.json.")
@click.option("--seed", type=int, default=0, show_default=True)
@click.option("--live/--no-live", default=None,
              help="Show the live supervisor view (default: when the output is a terminal).")
def demo(duration: float, speed: float, fail: str, robots: int, output: Path, seed: int,
         live: bool | None) -> None:
    """The patrol application end to end: simulator, agents and supervisor, then a summary."""
    logging.basicConfig(format="%(levelname)s %(name)s: %(message)s", level=logging.WARNING)
    try:
        main(duration, speed, fail, robots, output, seed, live)
    except MrtaRuntimeError as exc:
        raise RuntimeFailure(str(exc)) from exc
