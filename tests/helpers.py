"""Test helpers: free ports, child processes tracked by PID, line readers with deadlines.

Children are started with subprocess (never fork: a forked zenoh process hangs), get their own
rendezvous endpoint on a free port through $MRTA_RENDEZVOUS (never the default rendezvous port), and are ended by PID.
"""

from __future__ import annotations

import json
import os
import queue
import signal
import socket
import subprocess
import sys
import threading
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
PROCS = Path(__file__).resolve().parent / "procs"
REFERENCE = ROOT.parent / "shared" / "reference"
CONFIGS = ROOT / "configs"
ALLIANCE_ARCH = ROOT / "robot_agent" / "architecture"
PATROL = CONFIGS / "applications" / "patrol"
PATROL_WORLD = PATROL / "worlds" / "patrol.yaml"


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


class Child:
    def __init__(self, argv: list[str], env: dict, name: str):
        self.name = name
        self.argv = argv
        self.proc = subprocess.Popen(
            argv, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
            cwd=str(ROOT),
        )
        self.lines: "queue.Queue[str]" = queue.Queue()
        self.stdout: list[str] = []
        self.stderr: list[str] = []
        self._threads = [
            threading.Thread(target=self._pump, args=(self.proc.stdout, self.stdout, True), daemon=True),
            threading.Thread(target=self._pump, args=(self.proc.stderr, self.stderr, False), daemon=True),
        ]
        for t in self._threads:
            t.start()

    def _pump(self, stream, store, to_queue):
        for line in stream:
            line = line.rstrip("\n")
            store.append(line)
            if to_queue:
                self.lines.put(line)

    @property
    def pid(self) -> int:
        return self.proc.pid

    def wait_line(self, predicate, timeout: float, from_start: bool = False) -> str:
        """The first stdout line satisfying predicate (skipping others), or AssertionError.

        Lines are consumed as they are read; from_start=True also looks at lines consumed earlier
        (events that may have been printed before the line a test waited for first).
        """
        if from_start:
            for line in list(self.stdout):
                if predicate(line):
                    return line
        deadline = time.monotonic() + timeout
        while True:
            remaining = deadline - time.monotonic()
            if remaining <= 0:
                raise AssertionError(
                    f"{self.name}: no matching line within {timeout}s\nstdout: {self.stdout[-20:]}\n"
                    f"stderr: {self.stderr[-20:]}"
                )
            try:
                line = self.lines.get(timeout=min(remaining, 0.2))
            except queue.Empty:
                if self.proc.poll() is not None and self.lines.empty():
                    time.sleep(0.1)
                    if self.lines.empty():
                        raise AssertionError(
                            f"{self.name} exited ({self.proc.returncode}) before a matching line\n"
                            f"stdout: {self.stdout[-20:]}\nstderr: {self.stderr[-20:]}"
                        ) from None
                continue
            if predicate(line):
                return line

    def wait_stderr(self, predicate, timeout: float) -> str:
        """The first stderr line (logs, e.g. 'ready') satisfying predicate, or AssertionError."""
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            for line in list(self.stderr):
                if predicate(line):
                    return line
            if self.proc.poll() is not None:
                time.sleep(0.1)
                if not any(predicate(x) for x in self.stderr):
                    raise AssertionError(f"{self.name} exited ({self.proc.returncode})\n"
                                         f"stderr: {self.stderr[-20:]}")
            time.sleep(0.05)
        raise AssertionError(f"{self.name}: no matching stderr line within {timeout}s\n"
                             f"stderr: {self.stderr[-20:]}")

    def wait_json(self, predicate, timeout: float, from_start: bool = False) -> dict:
        def pred(line: str) -> bool:
            try:
                obj = json.loads(line)
            except ValueError:
                return False
            return isinstance(obj, dict) and predicate(obj)

        return json.loads(self.wait_line(pred, timeout, from_start))

    def signal(self, sig: int) -> None:
        if self.proc.poll() is None:
            os.kill(self.proc.pid, sig)

    def wait(self, timeout: float) -> int:
        rc = self.proc.wait(timeout=timeout)
        for t in self._threads:
            t.join(timeout=2)
        return rc

    def stop(self) -> None:
        if self.proc.poll() is None:
            self.signal(signal.SIGTERM)
            try:
                self.proc.wait(timeout=3)
            except subprocess.TimeoutExpired:
                self.signal(signal.SIGKILL)
                self.proc.wait(timeout=3)


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
