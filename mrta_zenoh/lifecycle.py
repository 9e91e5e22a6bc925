"""Clean shutdown on SIGINT / SIGTERM.

A signal only sets an event; the tool's main loop sees it and leaves its `with` blocks, which
undeclare everything and close the Zenoh session. Closing from inside a signal handler, or not
closing at all, is how a Zenoh process hangs at exit (docs/zenoh.md, "exit hang").
"""

from __future__ import annotations

import contextlib
import signal
import threading
from typing import Iterator


@contextlib.contextmanager
def stop_on_signals(stop: threading.Event | None = None) -> Iterator[threading.Event]:
    stop = stop or threading.Event()
    if threading.current_thread() is not threading.main_thread():
        yield stop  # signals can only be handled on the main thread (e.g. under CliRunner threads)
        return

    def handler(signum, frame):  # noqa: ARG001 - signal handler signature
        stop.set()

    previous = {s: signal.signal(s, handler) for s in (signal.SIGINT, signal.SIGTERM)}
    try:
        yield stop
    finally:
        for s, h in previous.items():
            signal.signal(s, h)
