"""`mrta experiment FILE.yaml` and `mrta experiment report DIR`: thin click wrappers over
mrta_supervisor.experiment.api (the runs) and mrta_supervisor.experiment.report_md (the report alone).

`experiment` is a group whose default command runs a file, so both spellings work: a first
argument that is not `report` (nor `run`, nor --help) is a file to run. Progress goes to
stderr, so stdout holds only the result (the summary's Overview a script reads, and which
sections summary.md holds besides): on a terminal a live bar
whose total is known from the start (it grows with each block of --until-ci); into a pipe or a
file one line per finished run, `[3/10] run002 ok, 12.4 s` — the count of runs done, then the
run's own name, the one its folder and results.csv's `run` column carry; nothing with `-q`.
Ctrl-C stops the runs, keeps the finished rows and exits 130.
"""

from __future__ import annotations

import contextlib
from pathlib import Path
from typing import Callable, Iterator

import click

from mrta_zenoh.cli.common import console, plural, verbosity
from mrta_zenoh.errors import ConfigError, MrtaRuntimeError
from mrta_zenoh.lifecycle import stop_on_signals
from mrta_zenoh.limits import MAX_RUNS

from .api import dry_run as check_only, parse_target, run_experiment
from .resume import Shard, merge_folders, parse_shard
from .runs import prepare_output
from .slurm_backend import TIME_LIMIT, SlurmOptions
from .report import Options
from .report_md import write_report

Progress = Callable[[int, int, "dict | None"], None]
RUN, REPORT = "run", "report"
BACKENDS = ("local", "dask", "slurm")
# click ≥ 8.2 raises this UsageError to show a group's help when it is given no arguments
NO_ARGS_IS_HELP = getattr(click.exceptions, "NoArgsIsHelpError", ())


@contextlib.contextmanager
def progress_reporter() -> Iterator[Progress | None]:
    """The progress callback for run_experiment: `(done, total, row)` as each run ends, and
    `(done, total, None)` when the total is known or grows. A live bar on a terminal's stderr,
    a line per run on a non-terminal stderr, None (silent) with -q."""
    if verbosity() < 0:
        yield None
        return
    err = console(stderr=True)
    if not err.is_terminal:
        def line(done: int, total: int, row: dict | None) -> None:
            if row is not None:
                click.echo(f"[{done}/{total}] run{row['run']:03d} {row['status']}, "
                           f"{row['wall_seconds']:.1f} s", err=True)
        yield line
        return
    from rich.progress import (BarColumn, MofNCompleteColumn, Progress as Bar, TextColumn,
                               TimeElapsedColumn)

    bar = Bar(TextColumn("[bold]runs"), BarColumn(), MofNCompleteColumn(), TimeElapsedColumn(),
              TextColumn("{task.description}"), console=err, transient=False)
    tasks: list = []

    def update(done: int, total: int, row: dict | None) -> None:
        if not tasks:  # drawn once the total is known: never `0/?`
            bar.start()
            tasks.append(bar.add_task("", total=total))
        last = "" if row is None else f"last: run{row['run']:03d} {row['status']}"
        bar.update(tasks[0], completed=done, total=total, description=last)
    try:
        yield update
    finally:
        if tasks:
            bar.stop()


@contextlib.contextmanager
def one_line_usage() -> Iterator[None]:
    """A usage error of the experiment verbs (an unknown option, a bad value, a missing
    argument) as one line and exit 2, like every other bad input of theirs (ConfigError),
    instead of click's three (usage, hint, error): `Error: mrta experiment run: No such option
    '--untl-ci'. Did you mean '--until-ci'?`."""
    try:
        yield
    except click.UsageError as exc:
        if isinstance(exc, NO_ARGS_IS_HELP):  # `mrta experiment` alone: its help, as asked
            raise
        where = exc.ctx.command_path if exc.ctx is not None else "mrta experiment"
        raise ConfigError(f"{where}: {' '.join(exc.format_message().split())} "
                          f"(`{where} --help` lists the options)") from None


class ExperimentGroup(click.Group):
    """`mrta experiment FILE …` runs FILE (the `run` command); `mrta experiment report DIR`
    makes the report of a finished one."""

    def parse_args(self, ctx: click.Context, args: list[str]) -> list[str]:
        if args and args[0] not in self.commands and args[0] not in ctx.help_option_names:
            args = [RUN, *args]
        return super().parse_args(ctx, args)

    def make_context(self, info_name, args, parent=None, **extra) -> click.Context:
        with one_line_usage():
            return super().make_context(info_name, args, parent, **extra)

    def invoke(self, ctx: click.Context):
        with one_line_usage():  # the subcommand's parsing and its option callbacks
            return super().invoke(ctx)

    def format_usage(self, ctx: click.Context, formatter: click.HelpFormatter) -> None:
        formatter.write_usage(ctx.command_path, "FILE.yaml [OPTIONS]  |  report RESULTS_DIR "
                                                "[RESULTS_DIR…] [OPTIONS]")


def _targets(ctx, param, values: tuple[str, ...]) -> dict[str, float]:
    try:
        return dict(parse_target(v) for v in values)
    except ConfigError as exc:
        raise click.BadParameter(exc.detail, ctx, param) from None


def _shard(ctx, param, value: str | None) -> Shard | None:
    try:
        return None if value is None else parse_shard(value)
    except ConfigError as exc:
        raise click.BadParameter(exc.detail, ctx, param) from None


def _metrics(ctx, param, values: tuple[str, ...]) -> tuple[str, ...] | None:
    names = tuple(m.strip() for v in values for m in v.split(",") if m.strip())
    return names or None


def report_options(f):
    """The options that shape a report, shared by both commands."""
    f = click.option("--baseline", metavar="NAME", default=None,
                     help="Compare every other architecture (or, with one architecture, every "
                          "other cell) with this one; default: the first in sorted order.")(f)
    f = click.option("--metrics", multiple=True, metavar="COLUMN[,COLUMN…]", callback=_metrics,
                     help="The results.csv columns to report (repeatable); default: every "
                          "measured column with numbers.")(f)
    f = click.option("--plots/--no-plots", default=True, show_default=True,
                     help="Draw pictures: with --no-plots, no run draws its own and the report "
                          "draws none (the recordings are kept: `mrta plot` draws any later).")(f)
    return f


@click.group(cls=ExperimentGroup, invoke_without_command=False, no_args_is_help=True,
             short_help="Run an experiment file's matrix of runs, or rebuild its report.")
def experiment() -> None:
    """Run an experiment file's matrix of runs and summarise it (`mrta experiment FILE.yaml
    [OPTIONS]`, the `run` command: `mrta experiment run --help` lists its options), or rebuild
    the report of a finished one from its results.csv (`mrta experiment report DIR`)."""


@experiment.command(RUN)
@click.argument("file", type=click.Path(dir_okay=False, path_type=Path))
@click.option("--output", type=click.Path(file_okay=False, path_type=Path),
              default=Path("experiment-output"), show_default=True,
              help="Folder for results.csv, summary.md, cells.csv, comparisons.csv, plots and "
                   "one folder per run.")
@click.option("--jobs", type=click.IntRange(min=1), default=None,
              show_default="one per CPU",
              help="Runs at once on this machine (each on its own private rendezvous).")
@click.option("--scheduler", metavar="tcp://HOST:PORT", default=None,
              help="Run every run as a task on this Dask cluster instead (workers started with "
                   "--resources runs=1; needs pip install 'mrta-zenoh[dask]').")
@click.option("--backend", type=click.Choice(BACKENDS), default=None,
              show_default="local, or dask with --scheduler",
              help="Where runs go: this machine (--jobs), a Dask cluster (--scheduler) or "
                   "SLURM job arrays (through submitit: pip install 'mrta-zenoh[slurm]'; "
                   "--output on a file system the nodes share).")
@click.option("--partition", metavar="NAME", default=None,
              help="With --backend slurm: the partition the array tasks go to (default: the "
                   "cluster's).")
@click.option("--array-size", type=click.IntRange(min=1), default=None,
              show_default="the cluster's MaxArraySize",
              help="With --backend slurm: at most this many runs an array.")
@click.option("--time-limit", type=click.IntRange(min=1), default=None,
              show_default=f"{TIME_LIMIT}",
              help="With --backend slurm: minutes an array task (one run) may take.")
@click.option("--max-runs", type=click.IntRange(min=1), default=MAX_RUNS, show_default=True,
              help="Refuse a matrix of more runs than this (seeds × failures × overrides); "
                   "with --until-ci, the cap on every run it adds too.")
@click.option("--agents-per-process", type=click.IntRange(min=1), default=None, metavar="K",
              show_default="the file's agents_per_process:, else 10",
              help="Run each run's robots' agents K per process (agent hosts: the same rows, "
                   "less CPU); 1: a process per robot. results.csv says which.")
@click.option("--fork-server/--no-fork-server", "warm", default=True, show_default=True,
              help="Fork every run's processes from one process that imported their "
                   "modules once (the same rows, ≈ a quarter less CPU), instead of starting "
                   "each as a fresh interpreter: one server for the experiment on this "
                   "machine (--jobs), one per run on a Dask worker or a SLURM array task.")
@click.option("--until-ci", "until", multiple=True, metavar="METRIC:HALF_WIDTH",
              callback=_targets,
              help="Add blocks of runs until the 95 % bootstrap interval of METRIC (a "
                   "results.csv column or a table's name for it) is narrower than "
                   "± HALF_WIDTH in every cell (repeatable), or --max-runs is reached: new "
                   "instances of every size when the file generates them, new seeds otherwise.")
@click.option("--block", type=click.IntRange(min=1), default=1, show_default=True,
              help="Instances (or seeds) each --until-ci block adds to every cell.")
@click.option("--shard", metavar="I/N", default=None, callback=_shard,
              help="Run only every N-th run of the matrix from the I-th (1 ≤ I ≤ N), on any "
                   "backend; `mrta experiment report` puts the shards' folders together.")
@click.option("--dry-run", is_flag=True,
              help="Check FILE as a run would (its instances made and read back, every "
                   "architecture, override and fault against each team) and say the matrix "
                   "and what --output already holds; run nothing, write nothing.")
@report_options
def run(file: Path, output: Path, jobs: int | None, scheduler: str | None,
        backend: str | None, partition: str | None, array_size: int | None,
        time_limit: int | None, max_runs: int, agents_per_process: int | None, warm: bool,
        until: dict[str, float], block: int, shard: Shard | None, dry_run: bool,
        baseline: str | None, metrics: tuple[str, ...] | None, plots: bool) -> None:
    """Run the matrix of FILE (seeds × failures × parameter overrides) and summarise it; on a
    folder holding an interrupted run of FILE, run only the runs it lacks."""
    slurm = _slurm_options(backend, scheduler, partition, array_size, time_limit)
    if dry_run:
        click.echo(check_only(file, output, shard, max_runs, until or None))
        return
    with stop_on_signals() as stop, progress_reporter() as progress:
        rows = run_experiment(file=file, output=output, jobs=jobs, stop=stop, progress=progress,
                              scheduler=scheduler, max_runs=max_runs, until=until or None,
                              block=block, plots=plots, shard=shard, slurm=slurm,
                              agents_per_process=agents_per_process, warm=warm,
                              report=Options(baseline=baseline, metrics=metrics))
    failed = sum(r["status"] != "ok" for r in rows)
    click.echo(f"{plural(len(rows), 'run')} ({failed} failed): {output / 'results.csv'}, "
               f"{output / 'summary.md'}, {output / 'cells.csv'}, "
               f"{output / 'comparisons.csv'}")
    click.echo(overview(output / "summary.md"))
    if failed:  # a sweep with holes is not a result: say so to scripts and CI (exit 1)
        raise MrtaRuntimeError(f"{failed} of {plural(len(rows), 'run')} failed: "
                               f"see {output / 'summary.md'}")


def _slurm_options(backend: str | None, scheduler: str | None, partition: str | None,
                   array_size: int | None, time_limit: int | None) -> SlurmOptions | None:
    """The SLURM options with --backend slurm; a ConfigError for a backend's option given to
    another backend (a --partition that would be ignored is a mistake to say, not to skip)."""
    if backend == "dask" and scheduler is None:
        raise ConfigError("--backend dask needs --scheduler tcp://HOST:PORT, the cluster's "
                          "scheduler")
    if backend in ("local", "slurm") and scheduler is not None:
        raise ConfigError(f"--scheduler is the Dask backend's: not with --backend {backend}")
    if backend != "slurm":
        given = [name for name, v in (("--partition", partition), ("--array-size", array_size),
                                      ("--time-limit", time_limit)) if v is not None]
        if given:
            raise ConfigError(f"{given[0]} is for --backend slurm")
        return None
    return SlurmOptions(partition, array_size, time_limit or TIME_LIMIT)


@experiment.command(REPORT)
@click.argument("results", metavar="RESULTS_DIR…", nargs=-1, required=True,
                type=click.Path(exists=True, path_type=Path))
@click.option("--output", type=click.Path(file_okay=False, path_type=Path), default=None,
              help="Folder for the report (default: RESULTS_DIR); with several folders, "
                   "required: their rows go there as one results.csv (and experiment.json).")
@report_options
def report(results: tuple[Path, ...], output: Path | None, baseline: str | None,
           metrics: tuple[str, ...] | None, plots: bool) -> None:
    """Rebuild summary.md, cells.csv, comparisons.csv and the plots from RESULTS_DIR's
    results.csv, running nothing; several folders of one experiment file (its shards) are
    reported as one."""
    folders = [r if r.is_dir() else r.parent for r in results]
    if len(folders) > 1:
        if output is None:
            raise ConfigError(f"{len(folders)} folders are reported as one into a folder of "
                              "their own: give --output OUT")
        source = merge_folders(folders, output)
    else:
        source = results[0]
        if output is not None:
            prepare_output(output)
    where = output or folders[0]
    write_report(source, output, Options(baseline=baseline, metrics=metrics, plots=plots))
    click.echo(overview(where / "summary.md"))


def overview(summary: Path) -> str:
    """What the verbs print of `summary`: its title, its lead and its Overview table, then
    which sections the file holds besides — the whole file, ≈ 600 lines for the study, buried
    the table a reader wanted (issue 51, the newcomer's list)."""
    parts = summary.read_text().rstrip().split("\n## ")
    if len(parts) <= 2:
        return "\n## ".join(parts)
    rest = ", ".join(p.split("\n", 1)[0].strip() for p in parts[2:])
    return "\n## ".join(parts[:2]).rstrip() + f"\n\nIn {summary} besides: {rest}."
