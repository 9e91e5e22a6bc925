"""Test helpers: free ports, child processes tracked by PID, line readers with deadlines, and
readiness from the liveliness tokens children declare (Tokens).

Children are started with subprocess (never fork: a forked zenoh process hangs), get their own
rendezvous endpoint on a free port through $MRTA_RENDEZVOUS (never the default rendezvous port), and are ended by PID.
"""

from __future__ import annotations

import json
import os
import socket
import struct
import sys
import threading
import time
from pathlib import Path

from mrta_zenoh import processes
from mrta_zenoh.errors import MrtaRuntimeError
from mrta_zenoh.keys import matches

TESTS = Path(__file__).resolve().parent.parent
ROOT = TESTS.parent
PROCS = TESTS / "procs"
REFERENCE = TESTS / "data" / "reference"  # the original project's files
CONFIGS = ROOT / "configs"
ALLIANCE_ARCH = ROOT / "robot_agent" / "alliance"
PATROL = CONFIGS / "applications" / "patrol"
PATROL_WORLD = PATROL / "worlds" / "patrol.yaml"

# Every wait these helpers offer is a hang guard, never a speed asserted: a timeout a test gives
# is raised to at least GUARD seconds. The CI machine runs the tests beside two CPU burners, and
# a child there may take 5–10 s for what takes 0.2 s on a quiet machine (measured: `mrta
# supervise` ended 0.1–6.4 s after SIGTERM at load 30, and two agents' tokens took over 20 s to
# come) — a test that fails because the machine was busy proves nothing about the code. A test
# that reads for a fixed window (collects what comes in N seconds) says so: `window=True`.
GUARD = 60.0


def guard(timeout: float | None) -> float | None:
    return None if timeout is None else max(timeout, GUARD)


def png_size(path: Path) -> tuple[int, int]:
    """(width, height) of a PNG file; fails if it is not one."""
    data = path.read_bytes()
    assert data[:8] == b"\x89PNG\r\n\x1a\n"
    return struct.unpack(">II", data[16:24])


def descendants(pid: int) -> list[int]:
    """Every process below `pid` (ours: started by a process this test started), from /proc."""
    out, todo = [], [pid]
    while todo:
        p = todo.pop()
        try:
            tasks = os.listdir(f"/proc/{p}/task")
        except OSError:
            continue
        for t in tasks:
            try:
                with open(f"/proc/{p}/task/{t}/children") as f:
                    kids = [int(x) for x in f.read().split()]
            except OSError:
                continue
            out += kids
            todo += kids
    return out


def kill_descendant(pid: int, *needles: str, dry_run: bool = False) -> int | None:
    """SIGKILL the first process below `pid` whose command line holds every one of `needles`
    (`dry_run`: only find it); its PID, or None if there is none (yet)."""
    import signal
    for d in descendants(pid):
        try:
            with open(f"/proc/{d}/cmdline", "rb") as f:
                argv = f.read().decode(errors="replace").split("\0")
        except OSError:
            continue
        if all(any(n in a for a in argv) for n in needles):
            if not dry_run:
                os.kill(d, signal.SIGKILL)
            return d
    return None


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


class Child(processes.Child):
    """The project's process manager's Child, started from the project folder; failures to
    produce a line are AssertionErrors, as tests expect."""

    def __init__(self, argv: list[str], env: dict, name: str):
        super().__init__(argv, name=name, env=env, cwd=str(ROOT))

    def wait(self, timeout: float | None = None) -> int:
        return super().wait(guard(timeout))

    def wait_line(self, predicate, timeout: float, from_start: bool = False, *,
                  window: bool = False) -> str:
        try:
            return super().wait_line(predicate, timeout if window else guard(timeout), from_start)
        except TimeoutError as exc:
            raise AssertionError(str(exc)) from None

    def wait_stderr(self, predicate, timeout: float) -> str:
        try:
            return super().wait_stderr(predicate, guard(timeout))
        except TimeoutError as exc:
            raise AssertionError(str(exc)) from None

    def stop(self) -> None:
        super().stop(grace=3.0)


class Demo(Child):
    """An `mrta demo` child (Children.demo) that knows its output folder."""

    def __init__(self, argv: list[str], env: dict, name: str, out: Path):
        super().__init__(argv, env, name)
        self.out = Path(out)

    def summary(self, timeout: float = 300, code: int = 0) -> dict:
        """The run's summary.json, once the demo has exited with `code` (else an
        AssertionError with the tail of its output)."""
        assert self.wait(timeout) == code, self.tail(30)
        return json.loads((self.out / "summary.json").read_text())


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

    def demo(self, out: Path, *args: str, quiet: bool = False, name: str = "demo") -> Demo:
        """`mrta [-q] demo --speed 0 --no-live --output OUT ARGS` started: the cross-process
        tests' one way to run a mission (`.summary()` waits for it and reads its summary). An
        option in ARGS given again wins over these (`--speed 1`: click keeps the last)."""
        argv = [*(["-q"] if quiet else []), "demo", "--speed", "0", "--no-live", "--output",
                str(out), *args]
        child = Demo([sys.executable, "-m", "mrta_zenoh.cli.main", *map(str, argv)], self.env,
                     name, out)
        self.all.append(child)
        return child

    def stop_all(self) -> None:
        for c in self.all:
            c.stop()


class Tokens:
    """Liveliness tokens on the children's bus, watched from the test process: a child is up once
    the token it declares is alive (docs/architecture.md, "Keys": agents `robotN/alliance/agent`
    or `robotN/murdoch/agent`, declared last; the simulator `@mrta/clock_source/<run>`; a
    recorder `@mrta/recorder/<zid>`), not once it has logged a line or a sleep has passed.

    By default a peer that connects to the children's rendezvous and never binds it, so the
    rendezvous stays the children's (a test may be about who holds it); it reconnects by retry
    as they do. `options` joins another way (a client of a router). Closed by its user; any left
    open when a test ends is closed then (tests/conftest.py): a session still open at exit hangs
    the interpreter (docs/zenoh.md, "Traps")."""

    open_watchers: set["Tokens"] = set()

    def __init__(self, rendezvous: str | None = None, options=None):
        from mrta_zenoh.bus import BusOptions
        from mrta_zenoh.bus.zenoh_bus import ZenohBus

        if options is None:
            options = BusOptions(connect=[rendezvous], listen=["tcp/127.0.0.1:0"])
        self._cond = threading.Condition()
        self.alive: set[str] = set()
        deadline = time.monotonic() + 15
        while True:  # a client's router may log that it listens a moment before it accepts
            try:
                self.bus = ZenohBus(options)
                break
            except MrtaRuntimeError:
                if time.monotonic() > deadline:
                    raise
                time.sleep(0.2)
        Tokens.open_watchers.add(self)
        # `**` never matches a chunk starting with `@`: infrastructure is watched on its own
        self._watches = [self.bus.watch_liveliness(k, self._on_token) for k in ("**", "@mrta/**")]

    def _on_token(self, key: str, up: bool) -> None:
        with self._cond:
            (self.alive.add if up else self.alive.discard)(key)
            self._cond.notify_all()

    def _until(self, found, what: str, timeout: float, procs) -> object:
        timeout = guard(timeout)
        deadline = time.monotonic() + timeout
        with self._cond:
            while True:
                result = found()
                if result:
                    return result
                for p in procs:
                    if p.proc.poll() is not None:
                        p.wait(2)  # its last lines read
                        raise processes.ChildExited(p)
                remaining = deadline - time.monotonic()
                if remaining <= 0:
                    tails = "".join(f"\n{p.name}: {p.tail()}" for p in procs)
                    raise AssertionError(f"{what} within {timeout} s; alive: "
                                         f"{sorted(self.alive)}{tails}")
                self._cond.wait(min(remaining, 0.2))

    def wait(self, pattern: str, timeout: float, *procs: Child, exclude=()) -> str:
        """The key of a live token under key expression `pattern` (not in `exclude`); an
        AssertionError if none within `timeout`, ChildExited as soon as one of `procs` ends."""
        def found():
            return min((k for k in self.alive if matches(pattern, k) and k not in exclude),
                       default=None)
        return self._until(found, f"no live token under {pattern}", timeout, procs)

    def wait_all(self, patterns, timeout: float, *procs: Child) -> list[str]:
        """One live token under each of `patterns` (see wait)."""
        patterns = list(patterns)

        def found():
            keys = [min((k for k in self.alive if matches(p, k)), default=None) for p in patterns]
            return keys if all(keys) else None
        return self._until(found, f"not every one of {patterns} alive", timeout, procs)

    def subscribed(self, key: str, timeout: float, *procs: Child) -> None:
        """Until a subscriber somewhere on the bus matches `key`: readiness of a child that
        declares no token (`mrta echo`), from Zenoh's own matching status."""
        pub = self.bus.session.declare_publisher(key)
        try:
            def found():
                status = pub.matching_status
                return getattr(status, "matching", status) is True
            self._until(found, f"no subscriber matching {key}", timeout, procs)
        finally:
            pub.undeclare()

    def wait_gone(self, key: str, timeout: float) -> None:
        self._until(lambda: key not in self.alive, f"{key} still alive", timeout, ())

    def close(self) -> None:
        if self not in Tokens.open_watchers:
            return
        Tokens.open_watchers.discard(self)
        for w in self._watches:
            w.close()
        self.bus.close()


class Wall:
    """A wall clock moved by hand (`wall.t += 3`): lockstep's timeouts tested without waiting
    for them, whatever the machine's speed. `read` holds what each thread read last, so a test
    can move it again only once the thread it holds up has seen the last move."""

    def __init__(self, t: float = 100.0):
        self.t = t
        self.read: dict[int, float] = {}

    def __call__(self) -> float:
        self.read[threading.get_ident()] = t = self.t
        return t


def wait_for(cond, timeout: float = 5.0, poll: float = 0.002) -> None:
    """Until `cond()` holds (another thread gets there); fails the test after `timeout`."""
    deadline = time.monotonic() + timeout
    while not cond():
        assert time.monotonic() < deadline, "condition not met"
        time.sleep(poll)


def claiming_step(stamp: float, step: int, sent: dict[str, int], run: str, timeout: float = 30.0,
                  table=None):
    """A lockstep Step (a forger's) claiming `sent` (key → count) with a whole key table: the
    keys of `table` (the simulator's, copied) first, then those of `sent` it lacks."""
    from mrta_zenoh.lockstep.protocol import Step
    from mrta_zenoh.lockstep.table import Claims, KeyTable

    keys = KeyTable()
    if table is not None:
        keys._append(list(table.keys))  # in the simulator's order
    keys.add(sent.keys())
    counts = Claims(keys, [sent.get(k, 0) for k in keys.keys]).packed()
    return Step(stamp, step, counts, list(keys.keys), 0, keys.digest, run, timeout)
