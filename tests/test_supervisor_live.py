"""What the live views leave on a terminal, read back through a terminal
emulator (pyte): log lines written while the view runs do not land across it, and neither a
view that changes shape nor a resized terminal leaves a stale header behind."""

from __future__ import annotations

import copy
import io
import logging
import re

import pyte
import pytest
from rich.console import Console, Group
from rich.text import Text

from mrta_agent.alliance.messages import InterRobotCommunication
from mrta_zenoh.cli.common import SafeFormatter
from mrta_zenoh.messages import Header
from mrta_supervisor.live.api import resolve_application
from mrta_supervisor.live.cli import LiveScreen
from mrta_supervisor.live.state import Supervisor
from mrta_supervisor.live.view import render

HEADER = "mrta demo · simulated"


class Terminal:
    """One tty: the console draws on it and the root logger's handler writes to it. pyte has
    no alternate screen: it is kept here (xterm's mode 1049: saved on entry, back on exit)."""

    ALT = re.compile(r"(\x1b\[\?1049[hl])")

    def __init__(self, columns: int, lines: int):
        self.screen = pyte.Screen(columns, lines)
        self.screen.set_mode(pyte.modes.LNM)  # a tty's onlcr: "\n" is a new line
        self.stream = pyte.Stream(self.screen)
        self.out = io.StringIO()
        self.fed = 0
        self.saved = None

    def resize(self, columns: int, lines: int, console: Console) -> None:
        """As a terminal that reflows does (VTE, kitty, iTerm2, Windows Terminal): the lines
        written so far are rewrapped to the new width, the cursor after the last of them."""
        self.pump()
        written = [line.rstrip() for line in self.screen.display[:self.screen.cursor.y + 1]]
        rows = [line[i:i + columns] for line in written
                for i in range(0, max(len(line), 1), columns)][-lines:]
        self.screen = pyte.Screen(columns, lines)
        self.screen.set_mode(pyte.modes.LNM)
        self.stream = pyte.Stream(self.screen)
        for i, row in enumerate(rows):
            self.screen.cursor_position(i + 1, 1)
            self.screen.draw(row)
        console.size = (columns, lines)

    def pump(self) -> list[str]:
        text = self.out.getvalue()
        for piece in self.ALT.split(text[self.fed:]):
            if piece == "\x1b[?1049h":
                self.saved = (copy.deepcopy(self.screen.buffer), copy.copy(self.screen.cursor))
                self.screen.erase_in_display(2)
            elif piece == "\x1b[?1049l" and self.saved is not None:
                self.screen.buffer.clear()
                self.screen.buffer.update(self.saved[0])
                self.screen.cursor = self.saved[1]
                self.saved = None
            else:
                self.stream.feed(piece)
        self.fed = len(text)
        return [line.rstrip() for line in self.screen.display]


@pytest.fixture
def terminal(monkeypatch):
    term = Terminal(120, 30)
    handler = logging.StreamHandler(term.out)
    handler.setFormatter(SafeFormatter("%(levelname)s %(name)s: %(message)s"))
    root = logging.getLogger()
    monkeypatch.setattr(root, "handlers", [handler])
    return term


def supervisor_with_alarms():
    app, arch = resolve_application("patrol")
    sup = Supervisor(arch, app, 0.0, unattended_after=1.0)
    sup.on_liveliness("robot1/alliance/agent", True, 0.0)
    sup.on_sample(sup.monitors, "robot1/alliance/inter_robot_communication",
                  "alliance_msgs/InterRobotCommunication",
                  InterRobotCommunication(Header("robot1", 0.5, 0), "wander", 60.0), 0.5)
    return sup


def frame(sup, now, width):
    header = Text(f"{HEADER} {now:5.1f} / 60 s", style="bold")
    return Group(header, render(sup.snapshot(now), width))


def test_log_lines_and_alarms_do_not_land_across_the_view(terminal):
    console = Console(file=terminal.out, force_terminal=True, width=120, height=30,
                      color_system=None)
    sup = supervisor_with_alarms()
    screen = LiveScreen(console)
    for i, now in enumerate((1.0, 2.0, 3.0, 4.0, 5.0)):
        sup.update(now)  # raises task_unattended for border_protection and report: alarm lines
        logging.getLogger("mrta.clock").warning("clock: a line while the view runs (%d)", i)
        screen.show(frame(sup, now, console.width))
    shown = terminal.pump()
    assert sum(HEADER in line for line in shown) == 1, "\n".join(shown)
    assert any("ALARM task_unattended report" in line for line in shown)
    assert not any("alarm: task_unattended" in line for line in shown)  # named once, in the view
    assert sum("a line while the view runs" in line for line in shown) == LiveScreen.KEEP
    screen.close()
    after = terminal.pump()
    # once the view is gone every held line is written out, and the alarms were not logged
    assert sum("a line while the view runs" in line for line in after) == 5
    assert not any("alarm:" in line for line in after)
    assert sum(HEADER in line for line in after) == 1  # the last picture stays, once


def test_a_resized_terminal_and_a_view_that_changes_shape_leave_nothing_stale(terminal):
    console = Console(file=terminal.out, force_terminal=True, width=120, height=30,
                      color_system=None)
    sup = supervisor_with_alarms()
    screen = LiveScreen(console)
    screen.show(frame(sup, 1.0, console.width))       # side by side: wide
    terminal.resize(60, 30, console)                  # narrower than its lines: rewrapped
    screen.show(frame(sup, 2.0, console.width))
    sup.update(3.0)                                   # alarms: the view grows
    screen.show(frame(sup, 3.0, console.width))
    terminal.resize(100, 24, console)
    screen.show(frame(sup, 4.0, console.width))
    shown = terminal.pump()
    assert sum(HEADER in line for line in shown) == 1, "\n".join(shown)
    assert sum("robots (Patrol, ALLIANCE)" in line for line in shown) == 1, "\n".join(shown)
    assert any("4.0 / 60 s" in line for line in shown)
    screen.close()


def test_piped_demo_lines_come_at_each_tenth_simulated_second_with_the_alarms():
    """Not on a terminal the demo prints a `t=` line at the first refresh past each 10th
    simulated second — the README's "every 10 simulated seconds" — naming the alarms up (the
    alarm log lines are off: the views name them)."""
    from mrta_supervisor.mission.cli import _Lines

    out = io.StringIO()
    lines = _Lines(Console(file=out, width=200, color_system=None))
    sup = supervisor_with_alarms()
    for now in (0.4, 1.6, 11.8, 12.9, 22.5, 30.0, 39.9, 40.0, 41.0):
        sup.update(now)
        lines(now, sup, None, None)
    shown = out.getvalue().splitlines()
    assert [line.split("s ")[0] for line in shown] == \
        ["t=  0.4", "t= 11.8", "t= 22.5", "t= 30.0", "t= 40.0"]
    assert "alarms: task_unattended border_protection" in shown[-1]
