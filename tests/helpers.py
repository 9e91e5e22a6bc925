"""Test helpers: free ports, child processes tracked by PID, line readers with deadlines.

Children are started with subprocess (never fork: a forked zenoh process hangs), get their own
rendezvous endpoint on a free port through $MRTA_RENDEZVOUS (never the default rendezvous port), and are ended by PID.
"""

from __future__ import annotations

import os
import socket
import struct
import sys
from pathlib import Path

from mrta_zenoh import processes

ROOT = Path(__file__).resolve().parent.parent
PROCS = Path(__file__).resolve().parent / "procs"
REFERENCE = ROOT.parent / "shared" / "reference"
CONFIGS = ROOT / "configs"
ALLIANCE_ARCH = ROOT / "robot_agent" / "alliance"
PATROL = CONFIGS / "applications" / "patrol"
PATROL_WORLD = PATROL / "worlds" / "patrol.yaml"


def png_size(path: Path) -> tuple[int, int]:
    """(width, height) of a PNG file; fails if it is not one."""
    data = path.read_bytes()
    assert data[:8] == b"\x89PNG\r\n\x1a\n"
    return struct.unpack(">II", data[16:24])


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


class Child(processes.Child):
    """The project's process manager's Child, started from the project folder; failures to
    produce a line are AssertionErrors, as tests expect."""

    def __init__(self, argv: list[str], env: dict, name: str):
        super().__init__(argv, name=name, env=env, cwd=str(ROOT))

    def wait_line(self, predicate, timeout: float, from_start: bool = False) -> str:
        try:
            return super().wait_line(predicate, timeout, from_start)
        except TimeoutError as exc:
            raise AssertionError(str(exc)) from None

    def wait_stderr(self, predicate, timeout: float) -> str:
        try:
            return super().wait_stderr(predicate, timeout)
        except TimeoutError as exc:
            raise AssertionError(str(exc)) from None

    def stop(self) -> None:
        super().stop(grace=3.0)


class Children:
    """Starts children with a private rendezvous endpoint; ends every one of them by PID."""

    def __init__(self) -> None:
        self.port = free_port()
        self.rendezvous = f"tcp/127.0.0.1:{self.port}"
        self.env = dict(os.environ)
        self.env["MRTA_RENDEZVOUS"] = self.rendezvous
        self.env["PYTHONUNBUFFERED"] = "1"
        self.env.setdefault("RUST_LOG", "error")
        self.all: list[Child] = []

    def python(self, script: str, *args: str, name: str | None = None) -> Child:
        child = Child([sys.executable, str(PROCS / script), *map(str, args)], self.env,
                      name or script)
        self.all.append(child)
        return child

    def mrta(self, *args: str, name: str | None = None) -> Child:
        child = Child([sys.executable, "-m", "mrta_zenoh.cli.main", *map(str, args)], self.env,
                      name or f"mrta {args[0]}")
        self.all.append(child)
        return child

    def stop_all(self) -> None:
        for c in self.all:
            c.stop()
