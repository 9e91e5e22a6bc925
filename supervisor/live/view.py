"""The live terminal view: robots, tasks, alarms and recent transitions, readable at 80×24.

Ids are never truncated (a user must be able to tell `robot10` from `robot1`): on a terminal
narrower than WIDE the robot and task tables are stacked instead of side by side. Everything
that came from the bus is shown as plain text — `Text(...)`, never a markup string — with
control characters made visible, so an id like `[/x]` or one holding terminal escape codes can
neither break the view nor style the screen.
"""

from __future__ import annotations

from rich import box
from rich.console import Group
from rich.table import Table
from rich.text import Text

from mrta_zenoh.untrusted import visible
from mrta_zenoh.yamlfile import plural

WIDE = 110  # columns from which the two tables stand side by side

STATE_STYLE = {"busy": "bold green", "idle": "yellow", "offline": "bold red", "unknown": "magenta",
               "allocated": "green", "unallocated": "red", "incoming": "yellow"}


def plain(value: object) -> Text:
    """Untrusted text as a Text: no markup parsed, control characters shown as \\xNN
    (mrta_zenoh.untrusted.visible)."""
    return Text(visible(value))


def render(snap: dict, width: int = 120) -> Group:
    t = snap["time"]
    robots = Table(box=box.SIMPLE_HEAD, pad_edge=False, expand=False, title_justify="left",
                   show_edge=False,
                   title=plain(f"robots ({snap['application']}, {snap['architecture']})"))
    for col in ("robot", "state", "task", "for"):
        robots.add_column(col, no_wrap=True, overflow="fold")
    for r in snap["robots"]:
        robots.add_row(plain(r["id"]), Text(r["state"], style=STATE_STYLE.get(r["state"], "")),
                       plain(r["task"] or "-"), Text(f"{t - r['since']:.0f}s"))
    tasks = Table(box=box.SIMPLE_HEAD, pad_edge=False, title="tasks", title_justify="left",
                  show_edge=False)
    for col in ("task", "state", "robots"):
        tasks.add_column(col, no_wrap=True, overflow="fold")
    for task in snap["tasks"]:
        tasks.add_row(plain(task["id"]), Text(task["state"], style=STATE_STYLE.get(task["state"], "")),
                      plain(",".join(task["robots"]) or "-"))
    if width >= WIDE:
        top = Table.grid(padding=(0, 2))
        top.add_row(robots, tasks)
        parts: list = [top]
    else:
        parts = [robots, tasks]
    idle = [r for r in snap["robots"] if r["state"] == "idle"]
    if idle:  # who stands idle, and whether work is waiting for a robot meanwhile (fairness)
        open_tasks = sum(1 for task in snap["tasks"] if task["state"] == "unallocated")
        line = Text("idle: ", style="bold yellow")
        line.append(plain(", ".join(f"{r['id']} {t - r['since']:.0f}s" for r in idle)))
        if open_tasks:
            line.append(plain(f" · {open_tasks} task(s) unallocated"))
        parts.append(line)
    if snap.get("processes"):
        line = Text("processes: ", style="bold")
        for p in snap["processes"]:
            line.append(plain(p["id"]))
            line.append(Text(" online  " if p["online"] else " offline  ",
                             style="green" if p["online"] else "bold red"))
        parts.append(line)
    if snap.get("run_ended"):  # robots keep the states the run left them in
        parts.append(Text(f"the run ended at {t:.1f} s: the picture is as it left it",
                          style="bold"))
    for a in snap["alarms"][-3:]:
        line = Text("ALARM ", style="bold red")
        line.append(plain(f"{a['kind']} {a['subject']} since {a['since']:.1f}s"))
        parts.append(line)
    room = 6 - min(3, len(snap["alarms"])) - (0 if width >= WIDE else 3) - (1 if idle else 0)
    for tr in snap["transitions"][-max(room, 1):]:
        text = plain(f"{tr['time']:9.1f}  {tr['kind']:<10} {tr['subject']:<24} "
                     f"{tr['from'] or '·'} → {tr['to'] or '·'}")
        text.stylize("dim")
        parts.append(text)
    ros2 = snap["ros2"]
    if ros2["nodes"]:
        line = Text(f"ROS 2 (domain {ros2['domain']}): ", style="bold")
        line.append(plain(", ".join(ros2["nodes"])))
        line.append(Text(f" · {plural(len(ros2['topics']), 'topic')}", style="dim"))
        parts.append(line)
    c = snap["counts"]
    parts.append(Text(f"t={t:.1f}s  samples {c['samples']}  wrong type {c['wrong_type']}  "
                      f"bad field {c['field_errors']}", style="dim"))
    return Group(*parts)
