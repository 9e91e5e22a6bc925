"""Plots from an MCAP recording: the allocation timeline (an architecture draws its own, e.g.
ALLIANCE's motivation panels in mrta_agent.alliance.plots).

Time axes are simulated seconds when the recording holds the simulator's `clock` (so a run at
`--speed 10` reads like the mission it simulated), wall seconds from the first message otherwise.
The timeline replays the recording through the same Supervisor the live view uses, with the
application's monitors, so it draws exactly what `mrta supervise` would have shown.
"""

from __future__ import annotations

import json
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
from mrta_zenoh import codec, keys  # noqa: E402
from mrta_zenoh.errors import ConfigError  # noqa: E402
from mrta_zenoh.files import save_figure  # noqa: E402
from mrta_zenoh.recording import TimeBase, read_recording  # noqa: E402
from mrta_zenoh.toolchain.model import Application, Architecture  # noqa: E402

from .state import Supervisor  # noqa: E402


def replay(records, tb: TimeBase, app: Application, arch: Architecture) -> Supervisor:
    """Feed a recording through a Supervisor, in recorded order, on recorded time."""
    start = tb(records[0][2]) if records else 0.0
    sup = Supervisor(arch, app, start, unattended_after=1e9, duplicate_after=1e9, quiet=True)
    by_key: dict[str, list] = {}
    last_update = start
    for k, enc, t, payload in records:
        now = tb(t)
        if k.startswith(keys.LIVELINESS_PREFIX):
            try:
                alive = json.loads(payload)["alive"]
            except (ValueError, KeyError, TypeError):
                continue
            sup.on_liveliness(k[len(keys.LIVELINESS_PREFIX):], bool(alive), now)
        else:
            monitors = by_key.get(k)
            if monitors is None:
                monitors = by_key[k] = [m for m in sup.monitors if keys.matches(m.key_expr, k)]
            if monitors:
                try:
                    type_name = codec.type_from_encoding(enc)
                    msg = codec.decode(type_name, payload)
                except codec.DecodeError:
                    continue
                sup.on_sample(monitors, k, type_name, msg, now)
        if now - last_update >= 0.05:
            sup.update(now)
            last_update = now
    end = tb(records[-1][2]) if records else start
    sup.update(end + max([m.topic.timeout for m in sup.monitors] + [0.0]))
    return sup


def allocation_intervals(sup: Supervisor, end: float) -> dict[str, list[tuple[str, float, float]]]:
    """robot → [(task, start, end)] from the supervisor's history."""
    open_: dict[tuple[str, str], float] = {}
    out: dict[str, list] = {}
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


def plot_timeline(recording: Path, app: Application, arch: Architecture, output: Path,
                  records: list | None = None, sup: Supervisor | None = None) -> Path:
    records = list(read_recording(recording)) if records is None else records
    if not records:
        raise ConfigError("the recording is empty", file=str(recording))
    tb = TimeBase(records)
    sup = replay(records, tb, app, arch) if sup is None else sup
    end = tb(records[-1][2])
    intervals = allocation_intervals(sup, end)
    robots = [r.id for r in app.robots] + sorted(set(intervals) - {r.id for r in app.robots})
    robots = [keys.normalize_robot_id(r) for r in robots]
    tasks = app.tasks() + sorted({t for iv in intervals.values() for t, _, _ in iv} - set(app.tasks()))
    colors = {t: plt.cm.tab10(i % 10) for i, t in enumerate(tasks)}
    offline = _offline_spans(sup, end)
    fig, ax = plt.subplots(figsize=(12, 1.0 + 0.6 * len(robots)), dpi=100)
    try:
        for row, rid in enumerate(robots):
            for task, a, b in intervals.get(rid, []):
                ax.broken_barh([(a, max(b - a, 1e-3))], (row - 0.35, 0.7), color=colors[task])
            for a, b in offline.get(rid, []):
                ax.broken_barh([(a, b - a)], (row - 0.35, 0.7), facecolor="none",
                               edgecolor="grey", hatch="//")
        ax.set_yticks(range(len(robots)), robots)
        ax.invert_yaxis()
        ax.set_xlabel(tb.label)
        ax.set_xlim(tb(records[0][2]), end)
        handles = [plt.Rectangle((0, 0), 1, 1, color=colors[t]) for t in tasks]
        handles.append(plt.Rectangle((0, 0), 1, 1, facecolor="none", edgecolor="grey", hatch="//"))
        ax.legend(handles, tasks + ["offline"], loc="upper center", ncol=len(tasks) + 1,
                  bbox_to_anchor=(0.5, -0.25 if len(robots) < 4 else -0.12), fontsize=8)
        ax.set_title(f"{app.name}: which robot did which task when")
        ax.grid(axis="x", alpha=0.3)
        fig.tight_layout()
        save_figure(fig, output)
    finally:
        plt.close(fig)
    return output


def _offline_spans(sup: Supervisor, end: float) -> dict[str, list[tuple[float, float]]]:
    spans: dict[str, list] = {}
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


