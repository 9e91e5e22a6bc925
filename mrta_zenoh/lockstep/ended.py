"""Which of a run's processes have ended, told to its simulator's barrier through a file that
only the run's own runner writes (`mrta sim --lockstep-ended FILE`), not through the bus.

Why not the bus: a participant token under a member's name proves nothing on an open bus.
Zenoh shows one token per key however many sessions declare it (one PUT, and a DELETE only
once the last is gone), so a forger's token under robot1's name keeps the name alive after
robot1's process has ended, and the barrier waited for it for its timeout (30 s; up to
WORK_LIMIT timeouts with forged work beats under its name). The runner knows its children: it
notes here each member whose process ended (`EndedWatch`), and the barrier gives such a member
up as soon as it is late (`read_ended`), counting the token that outlived it as refused. A
process on another machine (a fleet without a runner) is not covered: there the secured
fleet's ACL keeps other sessions from declaring a robot's token (docs/security.md).

The file: one name a line, appended whole (a line is far below PIPE_BUF, so a reader never
sees half of one, and a line without its newline is not read yet).
"""

from __future__ import annotations

import threading
from pathlib import Path
from typing import Callable, Mapping

POLL = 0.1  # wall seconds between two looks at the children


def read_ended(path: Path) -> frozenset[str]:
    """The names noted in `path` so far (none while it does not exist)."""
    try:
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError:
        return frozenset()
    return frozenset(line for line in text.split("\n")[:-1] if line)


class EndedWatch:
    """Notes in `path` each of `running`'s names (member → whether its process runs) once its
    process has ended, looking every POLL wall seconds on a thread of its own. A context
    manager: leaving it stops the thread (what has ended by then is noted first)."""

    def __init__(self, path: Path, running: Mapping[str, Callable[[], bool]]):
        self.path = path
        self.running = dict(running)
        self.noted: set[str] = set()
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._loop, name="lockstep-ended", daemon=True)

    def __enter__(self) -> EndedWatch:
        self.path.touch()
        self._thread.start()
        return self

    def __exit__(self, *exc) -> None:
        self._stop.set()
        self._thread.join()

    def look(self) -> None:
        """Note every member whose process has ended since the last look."""
        ended = [name for name, alive in self.running.items()
                 if name not in self.noted and not alive()]
        if ended:
            with self.path.open("a", encoding="utf-8") as f:
                for name in sorted(ended):
                    f.write(name + "\n")
            self.noted.update(ended)

    def _loop(self) -> None:
        while not self._stop.wait(POLL):
            self.look()
        self.look()
