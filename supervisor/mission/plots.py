"""Plots from an MCAP recording: the allocation timeline (an architecture draws its own, e.g.
ALLIANCE's motivation panels in mrta_agent.alliance.plots).

The timeline draws what the robots themselves said they did — the architecture's "who is
doing what" feed (`Architecture.read_doing`, ground_truth.py), in their own (simulated) time —
the same ground truth `mrta demo`'s summary prints, so the picture and the summary agree and
one seed gives one picture, byte for byte. The supervisor's view (`--view supervisor`, or
`both`) replays the recording through the same Supervisor the live view uses: it lags the
robots by its monitors' timeouts — what an operator saw, labelled as such, never the record.

Time axes are simulated seconds when the recording holds the simulator's `clock` (so a run at
`--speed 10` reads like the mission it simulated), wall seconds from the first message otherwise.
Tasks are in natural order (t2 before t10); `offline` is in the legend only when a robot was.
Each task has a colour of its own however many there are (mrta_zenoh.palette: tab10 repeated
after ten), the title names the architecture, and a run that ended when its work was over
marks that instant: the bars stop there because the summary's figures do (issue 51, the
newcomer's list: "timeline bars are clipped at the headline", with nothing saying why).
"""

from __future__ import annotations

import json
import math
import re
from dataclasses import dataclass, field
from pathlib import Path

from mrta_zenoh import codec, keys
from mrta_zenoh.architectures import architecture, architecture_names
from mrta_zenoh.errors import ConfigError
from mrta_zenoh.files import save_figure
from mrta_zenoh.palette import distinct_colors
from mrta_zenoh.recording import TimeBase, read_recording
from mrta_zenoh.tasks.messages import CHANGE
from mrta_zenoh.toolchain.model import ApplicationFile, ArchitectureFile

from .ground_truth import intervals_from
from ..live.state import Supervisor
from ..live.tasks import TaskWatch

Intervals = dict[str, list[tuple[str, float, float]]]  # robot → [(task, start, end)]
Spans = dict[str, list[tuple[float, float]]]           # robot → [(start, end)]
VIEWS = ("robots", "supervisor", "both")


@dataclass
class Panel:
    """One row block of the timeline: who did what (and who was offline), from one source."""

    title: str
    intervals: Intervals
    offline: Spans = field(default_factory=dict)


def replay(records, tb: TimeBase, app: ApplicationFile, arch: ArchitectureFile,
           watch: TaskWatch | None = None) -> Supervisor:
    """Feed a recording through a Supervisor, in recorded order, on recorded time."""
    start = tb(records[0][2]) if records else 0.0
    sup = Supervisor(arch, app, start, unattended_after=1e9, duplicate_after=1e9, quiet=True,
                     watch=watch)
    feed = watch.feed() if watch is not None else []
    by_key: dict[str, list] = {}
    last_update = start
    for k, enc, t, payload in records:
        now = tb(t)
        if k.startswith(keys.LIVELINESS_PREFIX):
            alive = _alive(payload)
            if alive is not None:
                sup.on_liveliness(k[len(keys.LIVELINESS_PREFIX):], alive, now)
        else:
            monitors = by_key.get(k)
            if monitors is None:
                monitors = by_key[k] = [m for m in sup.monitors if keys.matches(m.key_expr, k)]
            msg = _decoded(enc, payload) if monitors or any(
                keys.matches(e, k) for e, _ in feed) else None
            if msg is not None and monitors:
                sup.on_sample(monitors, k, codec.type_from_encoding(enc), msg, now)
            if msg is not None and any(keys.matches(e, k) for e, _ in feed):
                sup.on_task_sample(k, msg, now)
            if k == CHANGE:  # a task submitted or cancelled at run time
                sup.on_change(_decoded(enc, payload), now)
        if now - last_update >= 0.05:
            sup.update(now)
            last_update = now
    end = tb(records[-1][2]) if records else start
    sup.update(end + max([m.topic.timeout for m in sup.monitors] + [0.0]))
    return sup


def _decoded(enc: str, payload: bytes):
    try:
        return codec.decode(codec.type_from_encoding(enc), payload)
    except codec.DecodeError:
        return None


def _alive(payload: bytes) -> bool | None:
    try:
        alive = json.loads(payload)["alive"]
    except (ValueError, KeyError, TypeError):
        return None
    return bool(alive)


def allocation_intervals(sup: Supervisor, end: float) -> Intervals:
    """robot → [(task, start, end)] from the supervisor's history."""
    open_: dict[tuple[str, str], float] = {}
    out: Intervals = {}
    for tr in sup.history.all():
        if tr.kind != "allocation":
            continue
        task, robot = tr.subject.split("->", 1)
        if tr.new == "allocated":
            open_[(task, robot)] = tr.time
        elif (task, robot) in open_:
            out.setdefault(robot, []).append((task, open_.pop((task, robot)), min(tr.time, end)))
    for (task, robot), t0 in open_.items():
        out.setdefault(robot, []).append((task, t0, end))
    return out


def supervisor_offline(sup: Supervisor, end: float) -> Spans:
    """robot → when the supervisor showed it offline, after it had been up."""
    spans: Spans = {}
    went: dict[str, float] = {}
    for tr in sup.history.all():
        if tr.kind != "robot":
            continue
        if tr.new == "offline" and tr.old:
            went[tr.subject] = tr.time
        elif tr.old == "offline" and tr.subject in went:
            spans.setdefault(tr.subject, []).append((went.pop(tr.subject), tr.time))
    for rid, t0 in went.items():
        spans.setdefault(rid, []).append((t0, end))
    return spans


def recorded_offline(records, tb: TimeBase, end: float) -> Spans:
    """robot → when it held no liveliness token under `robotN/**` after it had held one (the
    recording's own liveliness changes, on its time axis)."""
    live: dict[str, set[str]] = {}
    went: dict[str, float] = {}
    spans: Spans = {}
    for k, _, t, payload in records:
        if not k.startswith(keys.LIVELINESS_PREFIX):
            continue
        key = k[len(keys.LIVELINESS_PREFIX):]
        alive = _alive(payload)
        if alive is None or key.startswith("@"):
            continue
        rid = keys.first_chunk(key)
        held = live.setdefault(rid, set())
        if alive:
            if not held and rid in went:
                spans.setdefault(rid, []).append((went.pop(rid), tb(t)))
            held.add(key)
        elif key in held:
            held.discard(key)
            if not held:
                went[rid] = tb(t)
    for rid, t0 in went.items():
        spans.setdefault(rid, []).append((t0, end))
    return spans


def robots_intervals(records, tb: TimeBase, arch_name: str, end: float) -> Intervals:
    """What the robots said they did (ground_truth.py), on the recording's time axis."""
    if arch_name not in architecture_names():
        raise ConfigError(f"architecture {arch_name!r} registers no contract "
                          "(mrta.architectures), so what its robots said cannot be read: "
                          "draw what the supervisor saw with --view supervisor")
    arch = architecture(arch_name)
    # stamps are the senders' clocks: simulated seconds, or Unix seconds on wall time
    shift = 0.0 if tb.simulated else tb.t0 / 1e9
    raw = intervals_from(records, arch, end + shift, arch.doing_stale_after)
    return {rid: [(task, a - shift, b - shift) for task, a, b in iv] for rid, iv in raw.items()}


def natural(text: str) -> list:
    """Sort key: `t2` before `t10`."""
    return [int(p) if p.isdigit() else p for p in re.split(r"(\d+)", text)]


WORK_OVER = "work over: the figures end here"


def architecture_title(app: ApplicationFile) -> str:
    """The architecture's display name (`ALLIANCE`), or its name if it registers none."""
    name = app.architecture
    return architecture(name).title if name in architecture_names() else name


def draw_timeline(output: Path, app: ApplicationFile, panels: list[Panel],
                  span: tuple[float, float], xlabel: str, *,
                  ended_at: float | None = None) -> Path:
    """Panels of rows (one per robot) of task bars, offline periods hatched, one legend;
    `ended_at`: when the run's work was over (its figures end there), marked, with a little
    of the axis after it."""
    import matplotlib  # ≈ 1.5 CPU-s to import: only where a picture is drawn (not --no-plots)
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    robots = [r.id for r in app.robots]
    for p in panels:
        robots += sorted(set(p.intervals) - set(robots))
    tasks = sorted(set(app.tasks()) | {t for p in panels for iv in p.intervals.values()
                                       for t, _, _ in iv}, key=natural)
    colors = dict(zip(tasks, distinct_colors(len(tasks))))
    if ended_at is not None:
        span = (span[0], ended_at + 0.04 * max(ended_at - span[0], 1.0))
    # a robot whose token goes as the run ends (every process stops) was not offline
    offline = any(b > a for p in panels for s in p.offline.values() for a, b in s)
    rows = len(robots) * len(panels)
    # the legend below, 8 entries a row: 0.3 inch for one row, 0.2 more for each further (a
    # 20-task run's three rows covered the axis' label)
    entries = len(tasks) + int(offline) + int(ended_at is not None)
    legend = 0.3 + 0.2 * (math.ceil(entries / 8) - 1)
    height = 1.0 + legend + 0.6 * rows + 0.5 * (len(panels) - 1)  # inches
    fig, axes = plt.subplots(len(panels), 1, sharex=True, squeeze=False,
                             figsize=(12, height), dpi=100)
    try:
        for ax, panel in zip(axes[:, 0], panels):
            for row, rid in enumerate(robots):
                for task, a, b in panel.intervals.get(rid, []):
                    ax.broken_barh([(a, max(b - a, 1e-3))], (row - 0.35, 0.7),
                                   color=colors[task])
                for a, b in panel.offline.get(rid, []):
                    ax.broken_barh([(a, b - a)], (row - 0.35, 0.7), facecolor="none",
                                   edgecolor="grey", hatch="//")
            if ended_at is not None:
                ax.axvline(ended_at, color="black", ls="--", lw=1)
            ax.set_yticks(range(len(robots)), robots)
            ax.invert_yaxis()
            ax.set_xlim(*span)
            ax.set_title(panel.title, fontsize=10)
            ax.grid(axis="x", alpha=0.3)
        axes[-1, 0].set_xlabel(xlabel)
        handles = [plt.Rectangle((0, 0), 1, 1, color=colors[t]) for t in tasks]
        labels = list(tasks)
        if offline:
            handles.append(plt.Rectangle((0, 0), 1, 1, facecolor="none", edgecolor="grey",
                                         hatch="//"))
            labels.append("offline")
        if ended_at is not None:
            handles.append(plt.Line2D([], [], color="black", ls="--", lw=1))
            labels.append(f"{WORK_OVER} ({ended_at:.1f} s)")
        arch = architecture_title(app)  # "Patrol (MURDOCH)" names it already
        fig.suptitle(f"{app.name if arch in app.name else f'{app.name} under {arch}'}: "
                     "which robot did which task when")
        fig.tight_layout(rect=(0, legend / height, 1, 1))
        fig.legend(handles, labels, loc="lower center", ncol=min(len(labels), 8), fontsize=8,
                   bbox_to_anchor=(0.5, 0.0), frameon=False)
        save_figure(fig, output)
    finally:
        plt.close(fig)
    return output


ROBOTS_TITLE = "what the robots said they did (the summary's ground truth)"
SUPERVISOR_TITLE = "what the supervisor showed (lags by its monitors' timeouts)"


def plot_timeline(recording: Path, app: ApplicationFile, arch: ArchitectureFile, output: Path,
                  view: str = "robots", watch: TaskWatch | None = None) -> Path:
    """`mrta plot timeline`: the robots' own account (`view` robots), the supervisor's
    (supervisor), or both, one above the other."""
    if view not in VIEWS:
        raise ConfigError(f"--view {view!r}: expected one of {', '.join(VIEWS)}")
    records = list(read_recording(recording))
    if not records:
        raise ConfigError("the recording is empty", file=str(recording))
    tb = TimeBase(records)
    start, end = tb(records[0][2]), tb(records[-1][2])
    panels = []
    if view in ("robots", "both"):
        panels.append(Panel(ROBOTS_TITLE, robots_intervals(records, tb, app.architecture, end),
                            recorded_offline(records, tb, end)))
    if view in ("supervisor", "both"):
        sup = replay(records, tb, app, arch, watch)
        panels.append(Panel(SUPERVISOR_TITLE, allocation_intervals(sup, end),
                            supervisor_offline(sup, end)))
    return draw_timeline(output, app, panels, (start, end), tb.label)
