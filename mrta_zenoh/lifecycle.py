"""Clean shutdown on SIGINT / SIGTERM, children that do not outlive their parent, and
resources closed by leaving their `with` blocks (Closing).

A signal only sets an event; the tool's main loop sees it and leaves its `with` blocks, which
undeclare everything and close the Zenoh session. Closing from inside a signal handler, or not
closing at all, is how a Zenoh process hangs at exit (docs/zenoh.md, "exit hang").
"""

from __future__ import annotations

import contextlib
import logging
import os
import signal
import threading
import time
from typing import Iterator, TypeVar

log = logging.getLogger("mrta.lifecycle")
_C = TypeVar("_C", bound="Closing")
PARENT_ENV = "MRTA_PARENT_PID"  # set by mrta_zenoh.processes for every child it starts
_received: list[int] = []  # the signals stop_on_signals handled in this process, in order


class Closing:
    """A resource that `close()` releases, used in a `with` block: `__enter__` returns it,
    `__exit__` closes it — contextlib.closing as a base class, so that every resource of the
    project (the bus and its handles, recorders, the barrier, servers, watches) is a context
    manager the same way."""

    __slots__ = ()

    def close(self) -> None:
        raise NotImplementedError(f"{type(self).__name__} must define close()")

    def __enter__(self: _C) -> _C:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def interrupted_by_user() -> bool:
    """Whether a SIGINT (Ctrl-C, or a parent stopping us) ended a run in this process: the
    program then exits 130, as Unix tools do (mrta_zenoh.cli.main.run), even though the run
    itself shut down cleanly. SIGTERM — a service manager's "please stop" — is a clean stop
    and leaves the exit code alone."""
    return signal.SIGINT in _received


def forget_signals() -> None:
    """A new program starts in this process (in-process test runs): no signal yet."""
    _received.clear()


@contextlib.contextmanager
def stop_on_signals(stop: threading.Event | None = None) -> Iterator[threading.Event]:
    stop = stop or threading.Event()
    if threading.current_thread() is not threading.main_thread():
        yield stop  # signals can only be handled on the main thread (e.g. under CliRunner threads)
        return

    def handler(signum, frame):  # noqa: ARG001 - signal handler signature
        _received.append(signum)
        stop.set()

    previous = {s: signal.signal(s, handler) for s in (signal.SIGINT, signal.SIGTERM)}
    try:
        yield stop
    finally:
        for s, h in previous.items():
            signal.signal(s, h)


def die_with_parent(poll: float = 0.5, grace: float = 10.0) -> threading.Thread | None:
    """If this process was started by mrta_zenoh.processes (whose pid is in $MRTA_PARENT_PID),
    stop it once that parent is gone — even after a `kill -9` of the parent, which leaves it no
    chance to stop its children: an orphaned simulator, agent or recorder would run for good.

    A daemon thread polls getppid() (a reparented process has another parent): when the parent
    is gone it sends this process SIGTERM, so the usual clean shutdown runs (a recorder finishes
    its file), and SIGKILL after `grace` seconds if that did not end it. Linux's
    PR_SET_PDEATHSIG would need a fork-time hook (forbidden once Zenoh is loaded) and fires when
    the parent *thread* ends, not the process. The variable is removed from this process's
    environment, so a process it starts by other means does not take this process for its
    parent."""
    value = os.environ.pop(PARENT_ENV, None)
    if value is None:
        return None
    try:
        parent = int(value)
    except ValueError:
        log.warning("ignoring $%s=%r: not a process id", PARENT_ENV, value)
        return None

    def watch() -> None:
        while os.getppid() == parent:
            time.sleep(poll)
        log.warning("parent process %d is gone: stopping", parent)
        os.kill(os.getpid(), signal.SIGTERM)
        time.sleep(grace)
        os.kill(os.getpid(), signal.SIGKILL)

    thread = threading.Thread(target=watch, name="die-with-parent", daemon=True)
    thread.start()
    return thread


POLL = 0.2  # seconds: how late a signal taken by another thread is seen at worst


def wait_for_stop(stop: threading.Event, timeout: float | None = None) -> bool:
    """`stop.wait(timeout)` in slices of POLL seconds; True once `stop` is set.

    Why not one wait: a process-directed SIGINT/SIGTERM may be delivered to any thread that
    does not block it — after SIGSTOP/SIGCONT (the signal pending while the process was
    stopped) it usually lands on one of Zenoh's threads. Python then only flags it, and runs
    the handler (which sets `stop`) when the main thread next executes bytecode: a main thread
    blocked in a wait without a timeout never does, so `mrta record` would ignore Ctrl-C for
    good and never finish its file (5 of 6 stopped-and-resumed recorders did). Waking every
    POLL seconds lets the handler run."""
    deadline = None if timeout is None else time.monotonic() + timeout
    while True:
        remaining = POLL if deadline is None else min(POLL, deadline - time.monotonic())
        if remaining <= 0:
            return stop.is_set()
        if stop.wait(remaining):
            return True
