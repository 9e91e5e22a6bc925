"""`mrta experiment run FILE --backend slurm`: the runs of a matrix as SLURM job arrays, through
submitit (the optional `slurm` extra: `pip install 'mrta-zenoh[slurm]'`).

University clusters are built around the job array: their schedulers, quotas and fair-share
count array tasks, not the long-lived workers a Dask cluster keeps (dask_backend.py, kept for
a lab's own machines). A run is one array task, for the reason it is one Dask task: `mrta demo`
and the processes it starts share one private loopback rendezvous, so they stay on one node.
The task (`run_task`) starts exactly the argv the local backend starts
(runs.start_run), writing straight into OUTPUT/runNNN — OUTPUT must be on a file
system the nodes share, as submitit's own folder (OUTPUT/slurm: its pickles and the tasks'
logs) must be — and, like the local backend, runs a run whose lockstep was not exact once
more before it returns. This process submits the arrays, then writes each run's row as its
task ends (runs.Results, the row the local backend makes), so the same seeds give
the same rows; resuming and shards (resume.py) work as on every backend: an
interrupted study is resumed by the same command, which submits only the runs without a row.

Arrays: a cluster refuses an array larger than its MaxArraySize (`scontrol show config`), so
the runs go in arrays of at most that many tasks (`--array-size K` for fewer: a quota on
queued tasks), submitted together; `array_parallelism` is left to the cluster's own limits.
A task is done when submitit's result file is there; a task that left the queue without one
(killed for its time limit, a node that died) is a failed row once `squeue` has not listed it
for two looks in a row — submitit's own check reads `sacct`, which a cluster without
accounting storage does not have. Ctrl-C cancels the tasks not yet ended (`scancel`) and keeps
the rows of those that had, as on the other backends. The tasks of one output folder share a
job name (`job_name`): a run into a folder whose earlier tasks are still queued or running (this
process killed, its tasks going on) is refused before anything is written, since both would
write the same run folders.
"""

from __future__ import annotations

import hashlib
import logging
import shutil
import subprocess
import threading
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from mrta_zenoh import forkserver
from mrta_zenoh.errors import ConfigError
from mrta_zenoh.processes import ProcessGroup
from mrta_zenoh.yamlfile import plural
from mrta_zenoh.toolchain.registry import Registry

from .file import Run
from .provenance import code_revision
from .runs import Results, error_of, inexact, start_run

log = logging.getLogger("mrta.experiment.slurm")

INSTALL = "pip install 'mrta-zenoh[slurm]'"
FOLDER = "slurm"         # OUTPUT/slurm: submitit's pickles and the tasks' logs
TIME_LIMIT = 60          # minutes per task, unless --time-limit says otherwise
OUTPUT_LINES = 20        # lines of a run's output sent back (the error cell shows the last 5)
SQUEUE_EVERY = 5.0       # seconds between looks at squeue for tasks gone without a result
POLL = 0.5               # seconds between looks at the result files


def require_submitit() -> Any:
    """The `submitit` module, or a ConfigError saying how to install it (an optional extra)."""
    try:
        import submitit
    except ImportError as exc:
        raise ConfigError(f"--backend slurm needs the `submitit` package ({exc}): "
                          f"{INSTALL}") from None
    return submitit


def max_array_size() -> int:
    """The cluster's MaxArraySize (`scontrol show config`): an array's largest index + 1; a
    ConfigError when there is no SLURM to ask."""
    if shutil.which("scontrol") is None or shutil.which("sbatch") is None:
        raise ConfigError("--backend slurm: no SLURM here (scontrol and sbatch not found): run "
                          "it on a cluster's login node")
    try:
        out = subprocess.run(["scontrol", "show", "config"], capture_output=True, text=True,
                             timeout=60, check=True).stdout
    except (subprocess.CalledProcessError, subprocess.TimeoutExpired) as exc:
        detail = getattr(exc, "stderr", "") or str(exc)
        raise ConfigError(f"--backend slurm: scontrol show config failed: "
                          f"{detail.strip()[:200]}") from None
    for line in out.splitlines():
        key, _, value = line.partition("=")
        if key.strip() == "MaxArraySize":
            return int(value.strip())
    return 1001  # SLURM's documented default


def chunks(runs: list[Run], size: int) -> list[list[Run]]:
    return [runs[i:i + size] for i in range(0, len(runs), size)]


# ------------------------------------------------------------------ on the node
@dataclass(frozen=True)
class SlurmTask:
    """One run, as pickled for an array task: what start_run needs, and where its folder is
    (on the shared file system)."""

    package: str
    duration: float
    run: Run
    out: str
    plots: bool = True
    warm: bool = True  # the run's processes forked by a fork server of the task's own


@dataclass
class TaskResult:
    returncode: int
    lines: list[str]   # the end of its output
    wall: float        # wall seconds of the run (the last try)
    code: str | None = None  # which code ran it: the node's (provenance.py)


def run_task(task: SlurmTask) -> TaskResult:
    """Run one mission on this node (the array task's function: importable by name, so the
    node unpickles it from its own install), once more if its lockstep was not exact. With
    `warm`, its processes (runner, recorder, simulator, agent hosts) are forked by a fork
    server the task starts (mrta_zenoh.forkserver: one import of the project instead of one a
    process; the same rows), ended with the task."""
    out = Path(task.out)
    package = Registry().find(task.package)
    with ProcessGroup() as group:
        for attempt in range(2):
            if out.exists():
                shutil.rmtree(out)
            out.mkdir(parents=True)
            t0 = time.monotonic()
            child = start_run(group, package, task.duration, task.run, out, task.plots,
                              warm=task.warm)
            rc = child.wait(None)
            wall = time.monotonic() - t0
            if attempt == 0 and inexact(out):
                continue
            break
        forkserver.finish(group)
    return TaskResult(rc, child.stdout[-OUTPUT_LINES:], wall, code_revision())


# ------------------------------------------------------------------ on the client
@dataclass(frozen=True)
class SlurmOptions:
    """Where and how long the array tasks run (`--partition`, `--array-size`, `--time-limit`)."""

    partition: str | None = None
    array_size: int | None = None     # at most this many tasks an array (and the cluster's max)
    time_limit: int = TIME_LIMIT      # minutes a task may take

    def check(self, output: Path) -> None:
        """Before anything is written: submitit installed, SLURM reachable, and no task of an
        earlier run into `output` still queued or running — it would write the run folder a
        resumed run writes (this process killed while its tasks went on)."""
        require_submitit()
        max_array_size()
        name = job_name(output)
        left = _queued(name=name)
        if left is None:
            raise ConfigError("--backend slurm: squeue cannot say which tasks are queued")
        if left:
            raise ConfigError(f"{plural(len(left), 'SLURM task')} of an earlier run into "
                              f"{output} still queued or running (job name {name}): they write "
                              f"the run folders this one would; wait for them, or `scancel "
                              f"--name {name}`, then run this again")


def job_name(output: Path) -> str:
    """The tasks' job name: the output folder's name and a digest of its full path, so the
    tasks of one folder are found by name (SlurmOptions.check, `scancel --name`)."""
    path = output.resolve()
    return f"mrta-{path.name[:40]}-{hashlib.sha1(str(path).encode()).hexdigest()[:6]}"


def run_on_slurm(*, packages: dict, duration: float, runs: list[Run], output: Path,
                 stop: threading.Event, results: Results, pictures: set[int] = frozenset(),
                 options: SlurmOptions = SlurmOptions(), warm: bool = True) -> None:
    """Every run as an array task; each run's row as its task ends. On `stop`: the tasks not
    ended are cancelled, the rows of those that had are kept."""
    submitit = require_submitit()
    from submitit.core.utils import FailedSubmissionError, UncompletedJobError

    size = max_array_size()
    if options.array_size is not None:
        size = min(size, options.array_size)
    executor = submitit.SlurmExecutor(folder=output / FOLDER / "%j")
    params: dict[str, Any] = {"time": options.time_limit, "cpus_per_task": 1,
                              "ntasks_per_node": 1, "job_name": job_name(output)}
    if options.partition is not None:
        params["partition"] = options.partition
    executor.update_parameters(**params)
    pending: dict[Any, Run] = {}
    for part in chunks(runs, max(1, size)):
        tasks = [SlurmTask(packages[r.architecture].name, duration, r,
                           str(output / f"run{r.index:03d}"), r.index in pictures, warm)
                 for r in part]
        try:
            jobs = executor.map_array(run_task, tasks)
        except (UncompletedJobError, FailedSubmissionError, OSError) as exc:  # sbatch's refusal
            _cancel(pending)
            raise ConfigError(f"--backend slurm: sbatch refused the array: "
                              f"{str(exc).strip().splitlines()[-1][:300]}") from None
        pending.update(zip(jobs, part))
        log.info("submitted array %s: %d runs", jobs[0].job_id.split("_")[0], len(part))
    gone: dict[str, int] = {}
    last_look = 0.0
    while pending and not stop.is_set():
        for job in [j for j in pending if j.paths.result_pickle.exists()]:
            _collect(job, pending.pop(job), output, results)
        if time.monotonic() - last_look > SQUEUE_EVERY and pending:
            last_look = time.monotonic()
            queued = _queued({j.job_id.split("_")[0] for j in pending})
            for job in list(pending):
                if queued is not None and job.job_id not in queued \
                        and not job.paths.result_pickle.exists():
                    gone[job.job_id] = gone.get(job.job_id, 0) + 1
                    if gone[job.job_id] >= 2:
                        _collect(job, pending.pop(job), output, results)
        stop.wait(POLL)
    if pending:  # stopped: keep what had finished, cancel the rest
        for job in [j for j in pending if j.paths.result_pickle.exists()]:
            _collect(job, pending.pop(job), output, results, only_clean=True)
        _cancel(pending)


def _queued(arrays: set[str] | None = None, name: str | None = None) -> set[str] | None:
    """The tasks squeue lists (one line each, -r) of these jobs or arrays, or of this job
    name, as submitit names them (ID_INDEX); None when squeue cannot say."""
    which = ["-j", ",".join(sorted(arrays))] if arrays is not None else ["-n", str(name)]
    try:
        out = subprocess.run(["squeue", "-h", "-r", "-o", "%i", *which],
                             capture_output=True, text=True, timeout=60)
    except (OSError, subprocess.TimeoutExpired):
        return None
    if out.returncode != 0 and "Invalid job id" not in out.stderr:
        return None
    return {line.strip() for line in out.stdout.splitlines() if line.strip()}


def _cancel(pending: dict) -> None:
    arrays = sorted({j.job_id.split("_")[0] for j in pending})
    if arrays:
        subprocess.run(["scancel", *arrays], capture_output=True, timeout=60)


def _collect(job, run: Run, output: Path, results: Results, only_clean: bool = False) -> None:
    """The row of a task that ended (with `only_clean`: only if its run exited 0)."""
    from submitit.core.utils import UncompletedJobError

    out = output / f"run{run.index:03d}"
    try:
        result: TaskResult = job.result()
    except UncompletedJobError as exc:  # the task raised (FailedJobError), or left no result
        if only_clean:
            return
        said = str(exc).strip().splitlines()
        out.mkdir(parents=True, exist_ok=True)
        results.add(run, out, 0.0, f"SLURM task {job.job_id}: {said[0] if said else exc}"[:400])
        return
    if only_clean and result.returncode != 0:
        return
    error = "" if result.returncode == 0 else error_of(result.returncode, result.lines)
    results.add(run, out, result.wall, error, result.code)
