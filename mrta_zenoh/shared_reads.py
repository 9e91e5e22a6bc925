"""Files read once per process while a scope asks for it: an agent host's robots share what
they would each have read alone.

Why: a robot's process reads its parameter files and the instance once, at start. An agent host
prepares K robots in one process, and each robot's preparation is the one its own process runs
(`AgentArchitecture.prepare`), so the files every robot of a package names — the instance, the
tasks file, the layers file — were read K times over: at 100 robots × 100 tasks, 400 YAML
documents and ≈ 40 CPU-s before the host could declare a robot alive (benchmarks/README.md,
agent hosts). Within `shared_reads()` a loader that goes through `once` parses a file once per
version of it (path, modification time and size: the key) and hands every later caller the same
document, which callers treat as read-only (frozen Structs and dataclasses, or a copy where a
caller owns a mutable container: `runtime.params.load_tasks_params`).

Outside the scope nothing is remembered: a robot's own process, the runner and the tools read
as before, and a file edited between two runs is read again. A read that fails is not
remembered either (its error is raised to the caller that asked)."""

from __future__ import annotations

import contextlib
import os
from collections.abc import Callable, Hashable, Iterator
from pathlib import Path
from typing import TypeVar

T = TypeVar("T")

_memo: dict[tuple, object] | None = None


@contextlib.contextmanager
def shared_reads() -> Iterator[None]:
    """Within this scope (nested scopes share the outer one's reads), `once` reads each file
    once. Not thread-safe: a host prepares its robots in one thread before any bus opens."""
    global _memo
    outer = _memo
    if outer is None:
        _memo = {}
    try:
        yield
    finally:
        _memo = outer


def once(path: Path | str, what: Hashable, read: Callable[[], T]) -> T:
    """`read()`, or — inside `shared_reads()` — what it gave for the same version of the file at
    `path` as `what` (the reader's name and any argument that changes its result)."""
    if _memo is None:
        return read()
    try:
        st = os.stat(path)
    except OSError:
        return read()  # the reader names the missing file in its own words
    key = (what, os.path.realpath(path), st.st_mtime_ns, st.st_size)
    if key not in _memo:
        _memo[key] = read()
    return _memo[key]  # type: ignore[return-value]
