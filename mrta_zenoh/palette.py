"""Colours for pictures that tell many robots or tasks apart (world.png, timeline.png).

matplotlib's tab10 repeats after ten: the 20-robot walkthrough drew robot1 and robot11 (and t1
and t11) alike (issue 51, the newcomer's list). Up to ten we keep tab10, so the pictures of the
shipped missions look as before; above, every colour is its own: hues evenly spread round the
circle, alternately strong and muted so that neighbours in the legend still differ.
"""

from __future__ import annotations

import colorsys

# matplotlib's tab10, as hex (what plt.cm.tab10(i) gives)
TAB10 = ("#1f77b4", "#ff7f0e", "#2ca02c", "#d62728", "#9467bd", "#8c564b", "#e377c2",
         "#7f7f7f", "#bcbd22", "#17becf")


def distinct_colors(n: int) -> list[str]:
    """`n` colours as "#rrggbb", all different."""
    if n <= len(TAB10):
        return list(TAB10[:n])
    out = []
    for i in range(n):
        s, v = (0.85, 0.85) if i % 2 == 0 else (0.55, 0.6)
        r, g, b = colorsys.hsv_to_rgb(i / n, s, v)
        out.append(f"#{round(r * 255):02x}{round(g * 255):02x}{round(b * 255):02x}")
    return out
