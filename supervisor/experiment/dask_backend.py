"""`mrta experiment FILE --scheduler tcp://HOST:PORT`: the runs of a matrix as tasks on a Dask
`distributed` cluster (the optional `dask` extra: `pip install 'mrta-zenoh[dask]'`).

A run is one task, because a run is `mrta demo` plus the processes it starts (simulator, agents,
recorder) on one private loopback rendezvous: they must all be on one machine. The task
(`run_task`) runs on a worker exactly the argv the local backend runs (runs.demo_args),
as a child of the worker, in a scratch folder under the worker's local directory, and returns
the exit code, the end of the output and the run folder's files as bytes (a few MB: run.mcap,
pictures, summary.json); the client writes them into OUTPUT/runNNN and makes the row the same
way the local backend does (runs.row_for), so the same seeds give the same rows. A run
of an instance (an experiment's `instances:` block) carries its instance file's bytes in the task:
the worker writes its own copy beside the run folder and hands it to `mrta demo --instance`, so
a worker on another machine needs no shared file system. Workers need mrta-zenoh and the
application's packages installed, as the client has.

How many runs a worker takes at once: every task asks for the Dask resource `runs=1`, and a
worker offers as many as it has room for, `dask worker ADDR --nthreads 1 --resources runs=1`
(a run in lockstep keeps about one core busy). A worker started without the resource gets no
run; if every worker lacks it, the experiment stops at once saying how to start them.

A worker that dies takes its run with it and the run is done again elsewhere: the scheduler
reassigns the tasks of a lost worker (up to its `distributed.scheduler.allowed-failures`
times; then the run is a failed row, KilledWorker), and a task that raises (a scratch folder
that cannot be written) is tried again `RETRIES` times. The run's processes die with the
worker: the child is started through mrta_zenoh.processes, which gives it $MRTA_PARENT_PID,
so `mrta demo` stops once its worker is gone (lifecycle.die_with_parent) and stops its own
children in turn. A Ctrl-C of the client sets a Dask Event the tasks poll, so running runs
stop their processes at once instead of running to their end for nobody; the rows of the runs
that had finished are kept, as on the local backend.
"""

from __future__ import annotations

import logging
import re
import tempfile
import threading
import time
import uuid
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from mrta_zenoh import forkserver
from mrta_zenoh.errors import ConfigError, MrtaRuntimeError
from mrta_zenoh.files import write_folder as files_write_folder
from mrta_zenoh.processes import ProcessGroup
from mrta_zenoh.toolchain.registry import Registry

from .file import Run
from .provenance import code_revision
from .runs import Results, error_of, package_copy, start_run

log = logging.getLogger("mrta.experiment.dask")

RESOURCE = "runs"        # what every run asks a worker for, one unit each
RETRIES = 2              # a task that raised is tried this many more times
POLL = 0.5               # seconds between a task's looks at the stop event (a scheduler call)
CONNECT_TIMEOUT = 20.0   # seconds to reach the scheduler
OUTPUT_LINES = 20        # lines of a run's output sent back (the error cell shows the last 5)
INSTALL = "pip install 'mrta-zenoh[dask]'"
_ADDRESS = re.compile(r"^(?:[a-z][a-z0-9+.-]*://)?(?:\[[0-9a-fA-F:]+\]|[^\s:/]+):\d{1,5}$")


def check_address(address: str) -> None:
    """A scheduler address is [PROTOCOL://]HOST:PORT (Dask's own form): refuse anything else
    before a connection attempt turns a typo into a 20-second wait."""
    if not _ADDRESS.match(address):
        raise ConfigError(f"--scheduler {address!r}: expected a Dask scheduler address, "
                          "tcp://HOST:PORT (e.g. tcp://127.0.0.1:8786)")


def require_distributed() -> Any:
    """The `distributed` module, or a ConfigError saying how to install it: it is an optional
    extra, imported only when a cluster is asked for."""
    try:
        import distributed
    except ImportError as exc:
        raise ConfigError(f"--scheduler needs Dask's `distributed` package ({exc}): "
                          f"{INSTALL}") from None
    return distributed


# ------------------------------------------------------------------ on the worker
@dataclass(frozen=True)
class RunTask:
    """One run, as sent to a worker: what `demo_args` needs, the stop event's name, and the
    run's instance file as bytes (a worker may be another machine: it writes its own copy)."""

    package: str
    duration: float
    run: Run
    stop_event: str
    plots: bool = True
    instance: bytes | None = None
    warm: bool = True  # the run's processes forked by a fork server of the task's own


@dataclass
class RunResult:
    """What a run left on its worker, sent back to the client."""

    returncode: int | None                 # None: stopped by the client's Ctrl-C
    lines: list[str]                       # the end of its output (stdout and stderr)
    wall: float                            # wall seconds the run's process took
    worker: str                            # the worker's address, for the log
    files: dict[str, bytes] = field(default_factory=dict)  # run folder: relative path → bytes
    code: str | None = None                # which code ran it: the worker's (provenance.py)


def run_task(task: RunTask) -> RunResult:
    """Run one mission on this worker (the task function: importable by name, so workers
    unpickle it from their own install). The child is started through ProcessGroup, so it
    carries $MRTA_PARENT_PID and dies with this worker; leaving the group stops it if this
    task ends first (a stop, an error)."""
    from distributed import Event, get_worker

    try:
        worker = get_worker()
        scratch, where = worker.local_directory, worker.address
    except ValueError:  # called outside a worker (a test, a debugger): the system's temp
        scratch, where = None, "local"
    stop = Event(task.stop_event)
    if stop.is_set():  # the client stopped while this run waited for a worker
        return RunResult(None, [], 0.0, where)
    name = f"run{task.run.index:03d}"
    with tempfile.TemporaryDirectory(prefix=f"mrta-{name}-", dir=scratch) as tmp:
        out = Path(tmp) / name
        out.mkdir()
        t0 = time.monotonic()
        stopped = False
        instance = None
        if task.instance is not None:  # beside the run folder, not in it: not sent back
            instance = Path(tmp) / task.run.instance.path.name
            instance.write_bytes(task.instance)
        with ProcessGroup() as group:
            child = start_run(group, Registry().find(task.package), task.duration, task.run,
                              out, task.plots, instance, warm=task.warm)
            while child.running():
                if stop.wait(POLL):
                    stopped = True
                    break
            if not stopped:
                forkserver.finish(group)
        rc = child.wait(10)
        wall = time.monotonic() - t0
        if stopped:
            return RunResult(None, child.stdout[-OUTPUT_LINES:], wall, where)
        return RunResult(rc, child.stdout[-OUTPUT_LINES:], wall, where, read_folder(out),
                         code_revision())


def read_folder(folder: Path) -> dict[str, bytes]:
    """Every file under `folder` by relative path, but hidden ones (the mission's lock file is
    the worker's business, not a result)."""
    files = {}
    for path in sorted(folder.rglob("*")):
        rel = path.relative_to(folder)
        if path.is_file() and not any(part.startswith(".") for part in rel.parts):
            files[rel.as_posix()] = path.read_bytes()
    return files


# ------------------------------------------------------------------ on the client
def write_folder(folder: Path, files: dict[str, bytes]) -> None:
    """A run folder from a worker's files, whole or not at all (files.write_folder: a Ctrl-C
    while writing leaves no half folder); a path that would leave the folder is refused first
    (what a worker sends is not trusted to stay inside it)."""
    for rel in files:
        parts = Path(rel).parts
        if Path(rel).is_absolute() or ".." in parts or not parts:
            raise MrtaRuntimeError(f"a worker sent a file outside its run folder: {rel!r}")
    files_write_folder(folder, files)


def _summary_here(out: Path) -> None:
    """summary.json names the folder the run wrote into: here, not the worker's scratch folder
    (gone with the task), as a run of the local backend names its own."""
    from ..mission.summary import read_summary, write_summary

    path = out / "summary.json"
    if path.is_file():
        summary = read_summary(path)
        summary.output = str(out)
        write_summary(path, summary)


def _workers(client) -> dict[str, dict]:
    """The scheduler's workers (address → info); recent versions list only a few unless asked
    for all."""
    try:
        info = client.scheduler_info(n_workers=-1)
    except TypeError:  # distributed before n_workers: it lists them all
        info = client.scheduler_info()
    return dict(info.get("workers", {}))


def check_workers(client, address: str) -> None:
    """Refuse a cluster whose workers all lack the `runs` resource: every run would wait for
    good. No worker at all is allowed (a batch system may still be starting them)."""
    workers = _workers(client)
    if not workers:
        log.warning("no worker at %s yet: the runs wait for workers started with "
                    "--resources %s=1", address, RESOURCE)
        return
    if not any((w.get("resources") or {}).get(RESOURCE) for w in workers.values()):
        raise ConfigError(f"no worker of the Dask cluster at {address} offers the "
                          f"{RESOURCE!r} resource every run asks for: start workers with "
                          f"`dask worker {address} --nthreads 1 --resources {RESOURCE}=1`")


def run_on_cluster(address: str, *, packages: dict, duration: float, runs: list[Run],
                   output: Path, stop: threading.Event, results: Results,
                   pictures: set[int] = frozenset(),
                   connect_timeout: float = CONNECT_TIMEOUT, warm: bool = True) -> None:
    """Every run as a task on the cluster at `address`; each run's folder and row as soon as it
    ends (the runs in `pictures` draw theirs). `packages`: the application package of each
    architecture of the runs. On `stop`: the runs that had finished cleanly are kept, the
    others stopped."""
    distributed = require_distributed()
    # fail here, as the local backend would at that run, rather than once per run on workers
    # (a run of an instance sets its overrides in the packages it derives: checked by
    # experiment.check_overrides on the first instance's)
    combos = {(run.architecture, run.overrides) for run in runs
              if run.overrides and run.instance is None}
    for arch, overrides in combos:
        with tempfile.TemporaryDirectory(prefix="mrta-overrides-") as tmp:
            package_copy(packages[arch].path, Path(tmp), overrides)
    texts = {run.instance.path: run.instance.path.read_bytes()
             for run in runs if run.instance is not None}
    try:
        client = distributed.Client(address, timeout=connect_timeout, set_as_default=False)
    except (OSError, TimeoutError) as exc:
        raise MrtaRuntimeError(f"cannot reach the Dask scheduler at {address}: {exc}") from None
    try:
        check_workers(client, address)
        token = uuid.uuid4().hex[:8]
        event = f"mrta-experiment-stop-{token}"
        futures = {}
        for run in runs:
            task = RunTask(packages[run.architecture].name, duration, run, event,
                           run.index in pictures,
                           texts[run.instance.path] if run.instance is not None else None,
                           warm)
            future = client.submit(run_task, task, key=f"mrta-run{run.index:03d}-{token}",
                                   resources={RESOURCE: 1}, retries=RETRIES)
            futures[future] = run
        while futures and not stop.is_set():
            for future in [f for f in futures if f.done()]:
                _gather(future, futures.pop(future), output, results)
            stop.wait(0.1)
        if futures:  # stopped: keep what had finished before, stop the rest on the workers
            finished = [f for f in futures if f.done()]
            distributed.Event(event, client=client).set()
            for future in finished:
                _gather(future, futures.pop(future), output, results, only_clean=True)
            client.cancel(list(futures))
    finally:
        client.close()


def _gather(future, run: Run, output: Path, results: Results, only_clean: bool = False) -> None:
    """The row (and folder) of a task that ended; with `only_clean`, only if its run exited 0."""
    out = output / f"run{run.index:03d}"
    if future.status == "finished":
        result: RunResult = future.result()
        future.release()
        if result.returncode is None or (only_clean and result.returncode != 0):
            return
        write_folder(out, result.files)
        if result.returncode == 0:
            _summary_here(out)
        log.debug("run %d ended on %s (exit %s)", run.index, result.worker, result.returncode)
        error = "" if result.returncode == 0 else error_of(result.returncode, result.lines)
        results.add(run, out, result.wall, error, result.code)
        return
    if only_clean:
        return
    # the task raised on every try, or killed too many workers (KilledWorker), or the cluster
    # dropped it: a failed row, as a run that crashed here is
    exc = future.exception() if future.status == "error" else None
    future.release()
    error = (f"{type(exc).__name__}: {exc}" if exc is not None
             else f"the cluster dropped the run ({future.status})")
    write_folder(out, {})  # an empty folder, as a run that failed here leaves its own
    results.add(run, out, 0.0, error[:400])
