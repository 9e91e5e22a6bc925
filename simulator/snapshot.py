"""A picture of the world: walls, its border and markers (if it has them), robots with heading,
sonar beams and trails.

Users would rather look than read: one PNG answers "where did the robots go and what did they see".
"""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")  # files only; never needs a display
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from matplotlib.collections import LineCollection  # noqa: E402
from matplotlib.patches import Circle  # noqa: E402
from mrta_zenoh.files import save_figure  # noqa: E402

from .engine import Simulation  # noqa: E402
from .sonar import sonar_origins  # noqa: E402


def save_snapshot(sim: Simulation, path: Path | str, title: str | None = None,
                  width_px: int = 1600) -> Path:
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
        ax.add_collection(LineCollection(sim.world.walls.reshape(-1, 2, 2), colors="black",
                                         linewidths=2))
        if sim.world.border is not None:
            b = np.vstack([sim.world.border, sim.world.border[:1]])
            ax.plot(b[:, 0], b[:, 1], "--", color="tab:orange", lw=1, label="border")
        for name, (mx, my) in sim.world.markers.items():  # above the robots: one may sit on it
            ax.plot(mx, my, "x", color="tab:red", ms=8, mew=2, zorder=5)
            ax.annotate(name, (mx, my), xytext=(6, -12), textcoords="offset points", fontsize=9,
                        color="tab:red", weight="bold", zorder=5)
        colors = plt.cm.tab10(np.arange(len(sim.ids)) % 10)
        if sim.trails is not None and len(sim.trails) > 1:
            trail = np.stack(sim.trails)  # (T, N, 2)
            for i in range(len(sim.ids)):
                ax.plot(trail[:, i, 0], trail[:, i, 1], "-", color=colors[i], lw=0.8, alpha=0.6)
        reading = sim.sonar()
        origins, dirs = sonar_origins(sim.pose, sim.sonars)
        ends = origins + dirs * reading.ranges.reshape(-1, 1)
        ax.add_collection(LineCollection(np.stack([origins, ends], axis=1), colors="tab:green",
                                         linewidths=0.4, alpha=0.5))
        r = sim.model.radius
        for i, rid in enumerate(sim.ids):
            x, y, th = sim.pose[i]
            ax.add_patch(Circle((x, y), r, color=colors[i], alpha=0.9))
            ax.plot([x, x + 1.6 * r * np.cos(th)], [y, y + 1.6 * r * np.sin(th)], "k-", lw=1)
            ax.annotate(rid, (x, y + 1.5 * r), ha="center", fontsize=8)
        ax.set_xlim(xmin, xmax)
        ax.set_ylim(ymin, ymax)
        ax.set_aspect("equal")
        ax.set_xlabel("x (m)")
        ax.set_ylabel("y (m)")
        ax.set_title(title or f"{sim.world.name} at t = {sim.time:.1f} s")
        fig.tight_layout()
        save_figure(fig, path)  # a half-written PNG never sits at the requested name
    finally:
        plt.close(fig)
    return path
