"""Child processes: the one manager behind `mrta launch`, `mrta demo`, experiments and the tests.

Children are started with subprocess (a fresh interpreter each, never a fork of a process that
has Zenoh loaded: docs/zenoh.md, "fork") — or, inside an experiment, by its fork server
(mrta_zenoh.forkserver: one process that imported the modules once and opens no session).
Their output is read line by line on threads, and they are the only processes this ever
signals — by PID, SIGINT first, SIGKILL after a grace period.
"""

from __future__ import annotations

import json
import os
import queue
import signal
import subprocess
import sys
import threading
import time
from typing import Callable, Iterable

from .forkserver import ForkedProcess, forkable
from .lifecycle import PARENT_ENV

LineSink = Callable[[str, str], None]  # (child name, line)


class Child:
    """One child process; stdout and stderr lines are kept (and optionally echoed)."""

    def __init__(self, argv: list[str], *, name: str, env: dict | None = None,
                 cwd: str | None = None, merge_stderr: bool = False,
                 echo: LineSink | None = None):
        self.name = name
        self.argv = argv
        # the child stops itself once this process is gone (lifecycle.die_with_parent), even
        # after a kill -9 of this one
        env = dict(os.environ if env is None else env)
        env[PARENT_ENV] = str(os.getpid())
        if forkable(argv, env):  # forked by the experiment's fork server: the same program, warm
            self.proc = ForkedProcess(argv, env, cwd, merge_stderr)
        else:
            self.proc = subprocess.Popen(
                argv, env=env, cwd=cwd, stdin=subprocess.DEVNULL, stdout=subprocess.PIPE,
                stderr=subprocess.STDOUT if merge_stderr else subprocess.PIPE, text=True)
        self.stdout: list[str] = []
        self.stderr: list[str] = []
        self.signalled: set[int] = set()  # the signals this process sent it (stop, kill)
        self.lines: "queue.Queue[str]" = queue.Queue()  # stdout lines not yet consumed
        self._echo = echo
        self._threads = [threading.Thread(target=self._pump, args=(self.proc.stdout, self.stdout, True),
                                          daemon=True)]
        if not merge_stderr:
            self._threads.append(threading.Thread(
                target=self._pump, args=(self.proc.stderr, self.stderr, False), daemon=True))
        for t in self._threads:
            t.start()

    def _pump(self, stream, store: list[str], to_queue: bool) -> None:
        for line in stream:
            line = line.rstrip("\n")
            store.append(line)
            if to_queue:
                self.lines.put(line)
            if self._echo is not None:
                self._echo(self.name, line)

    @property
    def pid(self) -> int:
        return self.proc.pid

    @property
    def returncode(self) -> int | None:
        return self.proc.poll()

    def running(self) -> bool:
        return self.proc.poll() is None

    def signal(self, sig: int) -> None:
        if self.proc.poll() is None:
            self.signalled.add(sig)
            os.kill(self.proc.pid, sig)

    def stopped_by_us(self) -> bool:
        """Ended the way a child we signalled ends: by the signal itself, cleanly (0), or with
        130 (Ctrl-C: mrta_zenoh.cli.main) after our SIGINT. Such an end is no failure, nor a
        child that ended by SIGINT after `interrupted()` (a Ctrl-C on the terminal reaches the
        whole process group, children included, before we signal them)."""
        rc = self.proc.poll()
        if rc is None or not self.signalled:
            return False
        return rc in (0, 128 + signal.SIGINT) or -rc in self.signalled

    def failed(self) -> bool:
        """Ended with an error: non-zero, or killed by a signal we did not send."""
        rc = self.proc.poll()
        return rc is not None and rc != 0 and not self.stopped_by_us()

    def describe_exit(self) -> str:
        """How it ended, for people: `exited with code 3`, `killed by SIGKILL`, `stopped`."""
        rc = self.proc.poll()
        if rc is None:
            return "running"
        if self.stopped_by_us():
            return "stopped"
        return describe_returncode(rc)

    def wait(self, timeout: float | None = None) -> int:
        rc = self.proc.wait(timeout=timeout)
        for t in self._threads:
            t.join(timeout=2)
        return rc

    def stop(self, grace: float = 5.0) -> int:
        """SIGINT (a clean shutdown: Zenoh sessions closed), SIGKILL after `grace` seconds, and
        then its end waited for without a bound: a SIGKILL always ends a process, but the
        kernel's tearing down of a big one gets the CPU slowly on a loaded machine — a 100-robot
        host (≈ 0.5 GB) at nice 19 and load 41 took over 5 s, and the whole `mrta demo` of a
        finished 20-minute mission ended with a TimeoutExpired traceback (issue 47)."""
        if self.proc.poll() is None:
            self.signal(signal.SIGINT)
            try:
                self.proc.wait(timeout=grace)
            except subprocess.TimeoutExpired:
                self.signal(signal.SIGKILL)
                self.proc.wait()
        return self.wait(grace)

    # ---- waiting for output (tests and tools that read a child's answers)
    def wait_line(self, predicate: Callable[[str], bool], timeout: float,
                  from_start: bool = False) -> str:
        """The first stdout line satisfying predicate (lines are consumed as read), or
        TimeoutError; from_start also looks at lines consumed earlier."""
        if from_start:
            for line in list(self.stdout):
                if predicate(line):
                    return line
        deadline = time.monotonic() + timeout
        while True:
            remaining = deadline - time.monotonic()
            if remaining <= 0:
                raise TimeoutError(f"{self.name}: no matching line within {timeout}s\n"
                                   f"stdout: {self.stdout[-20:]}\nstderr: {self.stderr[-20:]}")
            try:
                line = self.lines.get(timeout=min(remaining, 0.2))
            except queue.Empty:
                if self.proc.poll() is not None and self.lines.empty():
                    for t in self._threads:
                        t.join(timeout=1)
                    if self.lines.empty():
                        raise ChildExited(self) from None
                continue
            if predicate(line):
                return line

    def wait_json(self, predicate: Callable[[dict], bool], timeout: float,
                  from_start: bool = False, **how) -> dict:
        """The first stdout line that is a JSON object satisfying predicate; `how` goes to
        wait_line (a subclass's own options: the tests' harness takes `window`)."""
        def pred(line: str) -> bool:
            try:
                obj = json.loads(line)
            except ValueError:
                return False
            return isinstance(obj, dict) and predicate(obj)

        return json.loads(self.wait_line(pred, timeout, from_start, **how))

    def wait_stderr(self, predicate: Callable[[str], bool], timeout: float) -> str:
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            for line in list(self.stderr) + list(self.stdout):
                if predicate(line):
                    return line
            if self.proc.poll() is not None:
                for t in self._threads:
                    t.join(timeout=1)
                for line in list(self.stderr) + list(self.stdout):
                    if predicate(line):
                        return line
                raise ChildExited(self)
            time.sleep(0.05)
        raise TimeoutError(f"{self.name}: no matching stderr line within {timeout}s\n"
                           f"stderr: {self.stderr[-20:]}")

    def tail(self, n: int = 10) -> str:
        return "\n".join((self.stderr + self.stdout)[-n:])


def describe_returncode(rc: int) -> str:
    """`exited normally`, `exited with code 2`, `killed by SIGKILL` (subprocess gives -N for
    a child ended by signal N)."""
    if rc == 0:
        return "exited normally"
    if rc > 0:
        return f"exited with code {rc}"
    try:
        return f"killed by {signal.Signals(-rc).name}"
    except ValueError:
        return f"killed by signal {-rc}"


class ChildExited(AssertionError):
    """A child ended before producing what was waited for."""

    def __init__(self, child: Child):
        super().__init__(f"{child.name} exited ({child.proc.returncode}) before a matching line\n"
                         f"stdout: {child.stdout[-20:]}\nstderr: {child.stderr[-20:]}")
        self.child = child


def mrta_argv(*args: str) -> list[str]:
    """`mrta ARGS…` in this interpreter (children get the same environment as the parent)."""
    return [sys.executable, "-m", "mrta_zenoh.cli.main", *map(str, args)]


class ProcessGroup:
    """Children started together and ended together (reverse order), each only by its PID."""

    def __init__(self, env: dict | None = None, echo: LineSink | None = None):
        self.env = dict(os.environ if env is None else env)
        self.env.setdefault("PYTHONUNBUFFERED", "1")
        self.echo = echo
        self.children: list[Child] = []

    def start(self, argv: list[str], *, name: str, env: dict | None = None,
              merge_stderr: bool = False, cwd: str | None = None) -> Child:
        child_env = dict(self.env)
        child_env.update(env or {})
        child = Child(argv, name=name, env=child_env, cwd=cwd, merge_stderr=merge_stderr,
                      echo=self.echo)
        self.children.append(child)
        return child

    def failed(self, ignore: Iterable[str] = ()) -> list[Child]:
        """Children that ended with an error — a non-zero exit, or a signal this process did
        not send (a `kill -9` from outside is a failure) — except those named in `ignore`."""
        skip = set(ignore)
        return [c for c in self.children if c.name not in skip and c.failed()]

    def interrupted(self) -> None:
        """The user pressed Ctrl-C: the terminal sent SIGINT to every child as well, so a child
        that ends by it (or with 130) ended as asked, like one we stop ourselves."""
        for c in self.children:
            c.signalled.add(signal.SIGINT)

    def stop_all(self, grace: float = 5.0, later: Iterable[Child] = (),
                 later_grace: float = 5.0) -> None:
        """SIGINT to every child, SIGKILL to one still running `grace` seconds later. The
        children in `later` are signalled only once every other one has ended, and given
        `later_grace`: a recorder takes what the others said last, then writes out what it
        holds (killed after 5 s, a recorder behind on a busy machine lost the mission's end)."""
        last = [c for c in later if c in self.children]
        first = [c for c in reversed(self.children) if c not in last]
        for c in first:
            if c.running():
                c.signal(signal.SIGINT)
        for c in first:
            c.stop(grace)
        for c in last:
            c.stop(later_grace)

    def __enter__(self) -> "ProcessGroup":
        return self

    def __exit__(self, *exc: object) -> None:
        self.stop_all()
