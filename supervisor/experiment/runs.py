"""One run of an experiment, the same whichever backend starts it — here (api.py,
`--jobs`) or on a Dask worker (dask_backend.py, `--scheduler`): where a run's parameter
overrides go (a package copy, or its instance's derived packages: mission/overrides.py), the `mrta demo` argv, how a run is started, and how what it
left becomes a row of results.csv. Both backends import this module and nothing of each other.
"""

from __future__ import annotations

import contextlib
import os
import shutil
import sys
import tempfile
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from mrta_zenoh import forkserver
from mrta_zenoh.errors import ConfigError
from mrta_zenoh.failure import ROLES
from mrta_zenoh.installed import entry_points
from mrta_zenoh.planning.reference import REFERENCE_CACHE_ENV
from mrta_zenoh.processes import ProcessGroup, mrta_argv

from .file import Run
from .provenance import CODE_COLUMN, code_revision
from ..mission.overrides import Overrides, apply_overrides, override_text
from .results import COVERAGE, write_csv
from ..mission.summary import COMPLETE, INCOMPLETE, flat_metrics, read_summary, run_problem


REFERENCES = "references"  # beside a run's instance file: its solved reference values


@dataclass(frozen=True)
class Context:
    """What every run of one experiment shares, written into each row: with the run's own
    failure and overrides, the parameters that define its cell (results.py)."""

    mission: str = ""
    application: str = ""
    architecture: str = ""
    duration: float | None = None

    def columns(self) -> dict[str, Any]:
        return {k: v for k, v in (("mission", self.mission), ("application", self.application),
                                  ("architecture", self.architecture),
                                  ("duration", self.duration)) if v not in ("", None)}


def package_copy(pkg_path: Path, dest: Path, overrides: Overrides) -> Path:
    """A copy of the application's package with the overridden parameter values."""
    target = dest / pkg_path.name
    shutil.copytree(pkg_path, target, ignore=shutil.ignore_patterns("__pycache__", "*.py"))
    apply_overrides(target, overrides)
    return target


@contextlib.contextmanager
def bytecode_cache():
    """The environment of this experiment's runs: where this interpreter writes no bytecode
    (PYTHONDONTWRITEBYTECODE, as in this project's sandbox and many containers) and names no
    cache folder of its own, a folder of the experiment's own (PYTHONPYCACHEPREFIX) that the
    runs write their compiled modules to and read them back from; {} otherwise. Without it
    every process of every run — runner, recorder, simulator, agent host — compiled every
    module of the project from source again: ≈ 0.2 CPU-s a process, ≈ 1 CPU-s of a 5 / 5
    run's ≈ 13 (benchmarks/README.md, "The study's runs"). Bytecode is the same program: no
    row changes. The folder goes with the experiment; the user's tree gets no __pycache__."""
    if not sys.dont_write_bytecode or os.environ.get("PYTHONPYCACHEPREFIX"):
        yield {}
        return
    with tempfile.TemporaryDirectory(prefix="mrta-bytecode-") as folder:
        # an empty value is "not set" to Python (its documented rule for PYTHON* variables)
        yield {"PYTHONDONTWRITEBYTECODE": "", "PYTHONPYCACHEPREFIX": folder}


# What a run's processes import, once in the fork server instead of once a process (runner:
# `mrta demo`; recorder: `mrta record`; simulator, agent hosts and agents: executables) — the
# CLI, the verbs a run uses, and every executable, architecture and mission installed (the
# run's own are among them; the rest cost the server alone, once). What one of them imports
# later (a lazy import) its process imports itself: slower, never different.
WARM_GROUPS = (("mrta.commands", ("demo", "record")), ("mrta.executables", None),
               ("mrta.architectures", None), ("mrta.missions", None))
# scipy.optimize: the optimal assignment's (mrta_zenoh.planning.assignment imports it lazily),
# ≈ 1 CPU-s in the first run of each instance, whose analysis solves the reference the others
# read from the cache — once per experiment instead
WARM_MODULES = ("mrta_zenoh.cli.main", "mrta_zenoh.cli.run_node", "mrta_zenoh.recording",
                "scipy.optimize")


def warm_modules() -> list[str]:
    """The modules the experiment's fork server imports (mrta_zenoh.forkserver)."""
    names = list(WARM_MODULES)
    for group, only in WARM_GROUPS:
        names += [ep.module for ep in entry_points(group) if only is None or ep.name in only]
    return list(dict.fromkeys(names))


def demo_args(package: str, duration: float, run: Run, out: Path, plots: bool = True,
              instance: Path | None = None) -> list[str]:
    """`mrta ARGS…` for one run, whichever backend starts it: one spelling, so both run
    exactly the same mission. Without `plots` the run draws no picture (its recording and
    summary are the same: pictures are drawn from them). Its recording is the bus alone
    (`--recording bus`: what the analysis reads, ≈ 1.5 CPU-s a run less than a viewer's). `instance`: the run's instance file
    as this machine has it (a Dask worker writes its own copy); its overrides go to the
    packages the run derives from it (`--override`: mission/overrides.py)."""
    return (["-q", "demo", "--application", package, "--duration", str(duration), "--speed",
             "0", "--fail", run.failure, "--seed", str(run.seed), "--output", str(out),
             "--no-live", "--agents-per-process", str(run.agents_per_process),
             "--recording", "bus"]
            + ([] if plots else ["--no-plots"])
            + ([] if instance is None else ["--instance", str(instance)]
               + [a for k, v in run.overrides for a in ("--override", override_text(k, v))]))


def start_run(group: ProcessGroup, package, duration: float, run: Run, out: Path,
              plots: bool = True, instance: Path | None = None, warm: bool = False):
    """One run's mission as a child of `group`, writing into `out` (which exists): with its
    instance file (`instance`, default: the one in the experiment's output folder), or, without
    one, its own copy of the application package when the run overrides parameters. Runs of
    one instance share its reference values (REFERENCES), unless $MRTA_REFERENCE_CACHE names
    a folder of the caller's. `warm`: forked, with its processes, by the group's fork server
    (started by the first run that asks: mrta_zenoh.forkserver, `warm_modules`)."""
    if warm:
        forkserver.ensure(group, warm_modules())
    env = {}
    if instance is None and run.instance is not None:
        instance = run.instance.path
    if instance is not None and REFERENCE_CACHE_ENV not in os.environ:
        # the instance's reference values, solved by its first run's analysis and read by
        # the others' (mrta_zenoh.planning.reference): a folder beside the instance files
        env[REFERENCE_CACHE_ENV] = str(instance.parent / REFERENCES)
    if run.overrides and instance is None:
        package_copy(package.path, out / "package", run.overrides)
        env["MRTA_PACKAGE_PATH"] = str(out / "package")
    return group.start(mrta_argv(*demo_args(package.name, duration, run, out, plots, instance)),
                       name=f"run{run.index:03d}", env=env, merge_stderr=True)


def error_of(returncode: int, lines: list[str]) -> str:
    """The `error` cell of a run that did not exit 0: its code, the mission's own error line
    (which names the process that failed and its exit code) and the end of its output."""
    said = next((line for line in reversed(lines) if line.startswith("Error:")), "")
    tail = " | ".join(line for line in lines[-5:] if line.strip() and line != said)
    return (f"exit {returncode}: " + " | ".join(filter(None, [said, tail])))[-600:]


def row_for(run: Run, out: Path, wall: float, error: str = "",
            context: Context = Context(), code: str | None = None) -> dict:
    """The run's row: bookkeeping, the parameters of its cell (its instance's name and sizes
    with an instances block), then what it measured. `code`: which code ran it (provenance.py;
    default: this process's — a Dask or SLURM task's is its own machine's). A run of an instance leaves out coverage
    per task: task ids are the instance's own (t1 of one instance is not t1 of another), and
    a 100-task instance would add 300 columns no cell shares."""
    row: dict[str, Any] = {"run": run.index, "config": run.config, "seed": run.seed}
    row.update(context.columns())
    if run.architecture is not None:
        row["architecture"] = run.architecture
    if run.instance is not None:
        row.update({"instance": run.instance.name, "n_robots": run.instance.n_robots,
                    "n_tasks": run.instance.n_tasks})
    row["failure"] = run.failure
    row["agents_per_process"] = run.agents_per_process
    row.update({k: v for k, v in run.overrides})
    row.update({"status": "failed" if error else "ok", "error": error,
                "wall_seconds": round(wall, 2),
                CODE_COLUMN: code_revision() if code is None else code})
    if error:
        return row
    summary = read_summary(out / "summary.json")
    if summary.lockstep_exact is False:
        row["status"] = "inexact"
        row["error"] = run_problem(summary) + (" (fewer --jobs)" if summary.run_status == COMPLETE
                                               else "")
    measured = flat_metrics(summary)
    if run.instance is not None:
        measured = {k: v for k, v in measured.items() if not k.endswith(COVERAGE)}
    # the robot its fault struck: what a role (@first, @random) resolved to; blank when none
    # was struck (no fault, or an @first with nobody assigned before its time)
    f = summary.failure
    row["failed_robot"] = f.robot if f is not None and f.robot not in ROLES else ""
    row.update(measured)
    # counted by the run's own analysis (mission.message_rates), not by reading run.mcap again
    row["messages"] = "" if summary.messages.total is None else summary.messages.total
    return row


def inexact(out: Path) -> bool:
    """Whether the run in `out` wrote a summary that is not exact, or not complete (`mrta demo`
    then exits 1): summary.json's lockstep_exact and run_status."""
    try:
        summary = read_summary(out / "summary.json")
    except ConfigError:
        return False
    return summary.lockstep_exact is False or summary.run_status == INCOMPLETE


def prepare_output(output: Path) -> None:
    """The output folder, made (with its parents) before any run starts, or a ConfigError
    naming it."""
    try:
        output.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise ConfigError(f"--output: cannot make the folder: {exc.strerror}",
                          file=str(output)) from None
    if not os.access(output, os.W_OK | os.X_OK):
        raise ConfigError("--output: the folder is not writable", file=str(output))


class Results:
    """The rows of the runs that ended, in results.csv as soon as each ends (a Ctrl-C or a
    crash keeps them), the progress callback told: `progress(done, total, row)`, and
    `progress(done, total, None)` when the total is known or grows (a block of --until-ci).
    `rows`: those results.csv already held (a resumed folder: resume.done_rows), as
    read (strings), under their own columns first."""

    def __init__(self, path: Path, total: int, progress=None, context: Context = Context(),
                 rows: list[dict] | None = None):
        self.path, self.total, self.progress, self.context = path, total, progress, context
        self.rows: list[dict] = list(rows or [])
        self.fields: list[str] = list(self.rows[0]) if self.rows else []
        self.expect(total)

    def done(self) -> dict[int, dict]:
        """The rows by run number."""
        return {int(r["run"]): r for r in self.rows}

    def expect(self, total: int) -> None:
        self.total = total
        if self.progress is not None:
            self.progress(len(self.rows), total, None)

    def add(self, run: Run, out: Path, wall: float, error: str = "",
            code: str | None = None) -> dict:
        row = row_for(run, out, wall, error, self.context, code)
        self.rows.append(row)
        self.fields = write_csv(self.path, self.rows, self.fields)
        if self.progress is not None:
            self.progress(len(self.rows), self.total, row)
        return row

    def finish(self) -> list[dict]:
        """The rows in run order, results.csv rewritten in that order; with no row (stopped
        before the first run ended) no results.csv: a header-less file is not a table, and
        resuming from it would be refused."""
        self.rows.sort(key=lambda r: int(r["run"]))
        if self.rows:
            write_csv(self.path, self.rows, [])
        return self.rows
