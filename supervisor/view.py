"""The live terminal view: robots, tasks, alarms and recent transitions, sized for 80×24."""

from __future__ import annotations

from rich import box
from rich.console import Group
from rich.table import Table
from rich.text import Text

STATE_STYLE = {"busy": "bold green", "idle": "yellow", "offline": "bold red", "unknown": "magenta",
               "allocated": "green", "unallocated": "red", "incoming": "yellow"}


def render(snap: dict) -> Group:
    t = snap["time"]
    robots = Table(box=box.SIMPLE_HEAD, pad_edge=False, expand=False, title_justify="left",
                   title=f"robots ({snap['application']}, {snap['architecture']})")
    for col in ("robot", "state", "task", "for"):
        robots.add_column(col, no_wrap=True, overflow="ellipsis",
                          max_width={"robot": 10, "task": 18}.get(col))
    for r in snap["robots"]:
        robots.add_row(r["id"], Text(r["state"], style=STATE_STYLE.get(r["state"], "")),
                       r["task"] or "-", f"{t - r['since']:.0f}s")
    tasks = Table(box=box.SIMPLE_HEAD, pad_edge=False, title="tasks", title_justify="left")
    for col in ("task", "state", "robots"):
        tasks.add_column(col, no_wrap=True, overflow="ellipsis",
                         max_width={"task": 18, "robots": 14}.get(col))
    for task in snap["tasks"]:
        tasks.add_row(task["id"], Text(task["state"], style=STATE_STYLE.get(task["state"], "")),
                      ",".join(task["robots"]) or "-")
    top = Table.grid(padding=(0, 2))
    top.add_row(robots, tasks)
    lines = []
    for a in snap["alarms"][-3:]:
        lines.append(Text(f"ALARM {a['kind']} {a['subject']} since {a['since']:.1f}s",
                          style="bold red"))
    for tr in snap["transitions"][-(6 - min(3, len(snap["alarms"]))):]:
        lines.append(Text(f"{tr['time']:9.1f}  {tr['kind']:<10} {tr['subject']:<24} "
                          f"{tr['from'] or '·'} → {tr['to'] or '·'}", style="dim"))
    c = snap["counts"]
    footer = Text(f"t={t:.1f}s  samples {c['samples']}  wrong type {c['wrong_type']}  "
                  f"bad field {c['field_errors']}", style="dim")
    return Group(top, *lines, footer)
