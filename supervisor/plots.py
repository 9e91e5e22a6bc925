"""Plots from an MCAP recording: rqt_alliance's seven motivation panels and an allocation timeline.

Time axes are simulated seconds when the recording holds the simulator's `clock` (so a run at
`--speed 10` reads like the mission it simulated), wall seconds from the first message otherwise.
The timeline replays the recording through the same Supervisor the live view uses, with the
application's monitors, so it draws exactly what `mrta supervise` would have shown.
"""

from __future__ import annotations

import bisect
import json
from pathlib import Path
from typing import Iterator

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
from mcap.reader import make_reader  # noqa: E402

from mrta_zenoh import codec, keys  # noqa: E402
from mrta_zenoh.errors import ConfigError  # noqa: E402
from mrta_zenoh.messages import Motivation  # noqa: E402
from mrta_zenoh.toolchain.model import Application, Architecture  # noqa: E402

from .state import Supervisor  # noqa: E402


def read_recording(path: Path) -> Iterator[tuple[str, str, int, bytes]]:
    """(key, encoding, log_time_ns, payload) in log-time order."""
    try:
        f = open(path, "rb")
    except OSError as exc:
        raise ConfigError(f"cannot read recording: {exc.strerror}", file=str(path)) from None
    with f:
        try:
            reader = make_reader(f)
            for _schema, channel, message in reader.iter_messages(log_time_order=True):
                yield (channel.topic, channel.metadata.get("encoding", ""), message.log_time,
                       message.data)
        except Exception as exc:  # the mcap library raises many unrelated types for a bad file
            if isinstance(exc, ConfigError):
                raise
            raise ConfigError(f"not a readable MCAP file: {exc}", file=str(path)) from None


class TimeBase:
    """log time (ns) → seconds: simulated when a `clock` was recorded, else wall since start."""

    def __init__(self, records: list[tuple[str, str, int, bytes]]):
        self.logs: list[int] = []
        self.stamps: list[float] = []
        for key, enc, t, payload in records:
            if key == keys.CLOCK:
                try:
                    stamp = codec.decode(codec.type_from_encoding(enc), payload).stamp
                except (codec.DecodeError, AttributeError):
                    continue
                self.logs.append(t)
                self.stamps.append(stamp)
        self.t0 = records[0][2] if records else 0
        self.simulated = bool(self.logs)

    def __call__(self, t: int) -> float:
        if not self.simulated:
            return (t - self.t0) / 1e9
        i = bisect.bisect_right(self.logs, t) - 1
        return self.stamps[max(i, 0)]

    @property
    def label(self) -> str:
        return "simulated time (s)" if self.simulated else "time (s)"


def plot_motivation(recording: Path, robot: str, task: str, output: Path,
                    records: list | None = None) -> Path:
    records = list(read_recording(recording)) if records is None else records
    tb = TimeBase(records)
    key = keys.motivation(robot, task)
    rows = []
    for k, enc, t, payload in records:
        if k != key:
            continue
        try:
            msg = codec.decode(codec.type_from_encoding(enc), payload)
        except codec.DecodeError:
            continue
        if isinstance(msg, Motivation):
            rows.append((tb(t), msg))
    if not rows:
        found = sorted({k.rsplit("/", 1)[-1] for k, *_ in records if k.startswith(f"{robot}/alliance/motivation/")})
        raise ConfigError(f"no motivation samples for {robot} / {task} in the recording"
                          + (f" (tasks recorded for {robot}: {', '.join(found)})" if found else ""),
                          file=str(recording))
    ts = [r[0] for r in rows]
    panels = [("motivation", [m.motivation for _, m in rows]),
              ("impatience", [m.impatience for _, m in rows]),
              ("acquiescent", [m.acquiescent for _, m in rows]),
              ("suppressed", [m.suppressed for _, m in rows]),
              ("resetted", [m.resetted for _, m in rows]),
              ("applicable", [m.applicable for _, m in rows]),
              ("active", [m.active for _, m in rows])]
    fig, axes = plt.subplots(7, 1, figsize=(10, 12), dpi=100, sharex=True,
                             gridspec_kw={"height_ratios": [3, 2, 1, 1, 1, 1, 1]})
    try:
        for ax, (name, ys) in zip(axes, panels):
            if name in ("motivation", "impatience"):
                ax.plot(ts, ys, lw=1.2)
                if name == "motivation":
                    ax.plot(ts, [m.threshold for _, m in rows], "r--", lw=1, label="threshold")
                    ax.legend(loc="upper left", fontsize=8)
            else:
                ax.step(ts, [int(v) for v in ys], where="post", lw=1.2)
                ax.set_ylim(-0.2, 1.2)
                ax.set_yticks([0, 1])
            ax.set_ylabel(name, fontsize=9)
            ax.grid(alpha=0.3)
        axes[-1].set_xlabel(tb.label)
        fig.suptitle(f"{robot}: motivational behaviour for {task}")
        fig.tight_layout()
        _save(fig, output)
    finally:
        plt.close(fig)
    return output


def replay(records, tb: TimeBase, app: Application, arch: Architecture) -> Supervisor:
    """Feed a recording through a Supervisor, in recorded order, on recorded time."""
    start = tb(records[0][2]) if records else 0.0
    sup = Supervisor(arch, app, start, unattended_after=1e9, duplicate_after=1e9, quiet=True)
    by_key: dict[str, list] = {}
    last_update = start
    for k, enc, t, payload in records:
        now = tb(t)
        if k.startswith("@liveliness/"):
            try:
                alive = json.loads(payload)["alive"]
            except (ValueError, KeyError, TypeError):
                continue
            sup.on_liveliness(k[len("@liveliness/"):], bool(alive), now)
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
        _save(fig, output)
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


def _save(fig, output: Path) -> None:
    output = Path(output)
    tmp = output.with_name(output.name + ".tmp")
    fig.savefig(tmp, format="png")
    tmp.replace(output)
