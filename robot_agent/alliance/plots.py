"""rqt_alliance's seven motivation panels from a recording (`mrta plot motivation`, whose verb
is plot_cli.py).

ALLIANCE-specific, so it lives with ALLIANCE and joins `mrta plot` through the `mrta.plots`
entry points; the supervisor's plots know no architecture.
"""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

from mrta_zenoh import codec  # noqa: E402
from mrta_zenoh.errors import ConfigError  # noqa: E402
from mrta_zenoh.files import save_figure  # noqa: E402
from mrta_zenoh.recording import TimeBase, read_recording  # noqa: E402

from .architecture import ALLIANCE  # noqa: E402
from .messages import Motivation  # noqa: E402


def motivation_rows(records: list, tb: TimeBase) -> dict[str, list[tuple[float, Motivation]]]:
    """Every motivation sample of the recording by key, in one pass (the demo's panels used
    to decode the whole recording once per robot and task: 258 passes for 20 × 13)."""
    rows: dict[str, list[tuple[float, Motivation]]] = {}
    for k, enc, t, payload in records:
        if "/motivation/" not in k:
            continue
        try:
            msg = codec.decode(codec.type_from_encoding(enc), payload)
        except codec.DecodeError:
            continue
        if isinstance(msg, Motivation):
            rows.setdefault(k, []).append((tb(t), msg))
    return rows


def plot_motivation(recording: Path, robot: str, task: str, output: Path,
                    records: list | None = None) -> Path:
    records = list(read_recording(recording)) if records is None else records
    tb = TimeBase(records)
    rows = motivation_rows(records, tb).get(ALLIANCE.key(robot, "motivation", task), [])
    if not rows:
        prefix = ALLIANCE.key(robot, "motivation") + "/"
        found = sorted({k.rsplit("/", 1)[-1] for k, *_ in records if k.startswith(prefix)})
        raise ConfigError(f"no motivation samples for {robot} / {task} in the recording"
                          + (f" (tasks recorded for {robot}: {', '.join(found)})" if found else ""),
                          file=str(recording))
    return draw_motivation(rows, tb, robot, task, output)


def draw_motivation(rows: list[tuple[float, Motivation]], tb: TimeBase, robot: str, task: str,
                    output: Path) -> Path:
    """The seven panels of one robot's motivation for one task."""
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
        save_figure(fig, output)
    finally:
        plt.close(fig)
    return output
