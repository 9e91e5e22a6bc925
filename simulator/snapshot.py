"""A picture of the world: walls, its border and markers (if it has them), robots with heading,
sonar beams and trails, and a legend saying which is which.

Users would rather look than read: one PNG answers "where did the robots go and what did they see".
What a newcomer could not read off the first version (issue 51): which disc is which robot past
ten (tab10's colours repeated: mrta_zenoh.palette), which mark is a task (no legend), whose
label a disc hid, under which architecture the run was (`label`), and which robots had
crashed — drawn like the living. The simulator knows no fault: a robot `gone` is one whose
process was up and had none left at the end (its liveliness tokens went with its session: a
crash, or a cut that lasted to the end; a robot driven by a script that declares no token is
not gone), drawn hollow and hatched, "(no process)" beside its name.
"""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")  # files only; never needs a display
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from matplotlib.collections import LineCollection  # noqa: E402
from matplotlib.lines import Line2D  # noqa: E402
from matplotlib.patches import Circle, Patch  # noqa: E402
from mrta_zenoh.files import save_figure  # noqa: E402
from mrta_zenoh.palette import distinct_colors  # noqa: E402

from .engine import Simulation  # noqa: E402
from .sonar import sonar_origins  # noqa: E402


GONE = "no process at the end (crashed, or cut off)"
LABEL_BOX = {"boxstyle": "round,pad=0.15", "facecolor": "white", "edgecolor": "none",
             "alpha": 0.75}


def save_snapshot(sim: Simulation, path: Path | str, title: str | None = None,
                  width_px: int = 1600, label: str | None = None,
                  gone: frozenset[str] | set[str] = frozenset()) -> Path:
    """`label`: what ran the robots (the architecture), in the title; `gone`: robots drawn as
    having no process left."""
    path = Path(path)
    xmin, ymin, xmax, ymax = sim.world.bounds
    xs, ys = sim.pose[:, 0], sim.pose[:, 1]
    xmin, xmax = min(xmin, xs.min()) - 1, max(xmax, xs.max()) + 1
    ymin, ymax = min(ymin, ys.min()) - 1, max(ymax, ys.max()) + 1
    aspect = (ymax - ymin) / max(xmax - xmin, 1e-6)
    dpi = 100
    fig_w = width_px / dpi
    fig, ax = plt.subplots(figsize=(fig_w, max(3.0, fig_w * aspect + 0.8)), dpi=dpi)
    try:
        legend = [Line2D([], [], color="black", lw=2, label="wall")]
        ax.add_collection(LineCollection(sim.world.walls.reshape(-1, 2, 2), colors="black",
                                         linewidths=2))
        if sim.world.border is not None:
            b = np.vstack([sim.world.border, sim.world.border[:1]])
            legend += ax.plot(b[:, 0], b[:, 1], "--", color="tab:orange", lw=1, label="border")
        for name, (mx, my) in sim.world.markers.items():  # above the robots: one may sit on it
            ax.plot(mx, my, "x", color="tab:red", ms=8, mew=2, zorder=5)
            ax.annotate(name, (mx, my), xytext=(6, -12), textcoords="offset points", fontsize=9,
                        color="tab:red", weight="bold", zorder=6, bbox=LABEL_BOX)
        if sim.world.markers:
            legend.append(Line2D([], [], color="tab:red", marker="x", ms=8, mew=2, ls="",
                                 label="task (marker)"))
        colors = distinct_colors(len(sim.ids))
        if sim.trails is not None and len(sim.trails) > 1:
            trail = np.stack(sim.trails)  # (T, N, 2)
            for i in range(len(sim.ids)):
                ax.plot(trail[:, i, 0], trail[:, i, 1], "-", color=colors[i], lw=0.8, alpha=0.6)
            legend.append(Line2D([], [], color="grey", lw=0.8, label="trail (robot's colour)"))
        reading = sim.sonar()
        origins, dirs = sonar_origins(sim.pose, sim.sonars)
        ends = origins + dirs * reading.ranges.reshape(-1, 1)
        ax.add_collection(LineCollection(np.stack([origins, ends], axis=1), colors="tab:green",
                                         linewidths=0.4, alpha=0.5))
        legend.append(Line2D([], [], color="tab:green", lw=0.8, label="sonar beams"))
        r = sim.model.radius
        for i, rid in enumerate(sim.ids):
            x, y, th = sim.pose[i]
            if rid in gone:
                ax.add_patch(Circle((x, y), r, facecolor="white", edgecolor=colors[i],
                                    hatch="xx", lw=1.5))
            else:
                ax.add_patch(Circle((x, y), r, color=colors[i], alpha=0.9))
            ax.plot([x, x + 1.6 * r * np.cos(th)], [y, y + 1.6 * r * np.sin(th)], "k-", lw=1)
            ax.annotate(rid + (" (no process)" if rid in gone else ""), (x, y + 1.5 * r),
                        ha="center", fontsize=8, zorder=6, bbox=LABEL_BOX)
            legend.append(Patch(color=colors[i], label=rid))
        if gone:
            legend.append(Patch(facecolor="white", edgecolor="black", hatch="xx", label=GONE))
        ax.set_xlim(xmin, xmax)
        ax.set_ylim(ymin, ymax)
        ax.set_aspect("equal")
        ax.set_xlabel("x (m)")
        ax.set_ylabel("y (m)")
        under = f" under {label}" if label else ""
        ax.set_title(title or f"{sim.world.name}{under} at t = {sim.time:.1f} s "
                              "(the simulation's end)")
        ax.legend(handles=legend, loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=8,
                  ncol=1 + len(legend) // 30, frameon=False)
        fig.tight_layout()
        save_figure(fig, path)  # a half-written PNG never sits at the requested name
    finally:
        plt.close(fig)
    return path
