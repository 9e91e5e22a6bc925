"""`mrta experiment FILE.yaml`: a thin click wrapper over mrta_supervisor.experiment.

Progress goes to stderr, as runs end, so stdout holds only the result (the summary a script
reads): on a terminal a live bar; into a pipe or a file one plain line per finished run
(`run 3/10: ok, 12.4 s`), nothing with `-q`. The bar used to go to stdout, where rich draws a
non-terminal only at the end. Ctrl-C stops the runs, keeps the finished rows and exits 130
(mrta_zenoh.errors.Interrupted, translated once in mrta_zenoh.cli.main).
"""

from __future__ import annotations

import contextlib
from pathlib import Path
from typing import Callable, Iterator

import click

from mrta_zenoh.cli.common import console, plural, verbosity
from mrta_zenoh.errors import MrtaRuntimeError
from mrta_zenoh.lifecycle import stop_on_signals
from mrta_zenoh.limits import MAX_RUNS

from .experiment import run_experiment

Progress = Callable[[int, int, dict], None]


@contextlib.contextmanager
def progress_reporter() -> Iterator[Progress | None]:
    """The progress callback for run_experiment: a live bar on a terminal's stderr, a line per
    run on a non-terminal stderr, None (silent) with -q."""
    if verbosity() < 0:
        yield None
        return
    err = console(stderr=True)
    if not err.is_terminal:
        def line(done: int, total: int, row: dict) -> None:
            click.echo(f"run {done}/{total}: run {row['run']} {row['status']}, "
                       f"{row['wall_seconds']:.1f} s", err=True)
        yield line
        return
    from rich.progress import (BarColumn, MofNCompleteColumn, Progress as Bar, TextColumn,
                               TimeElapsedColumn)

    with Bar(TextColumn("[bold]runs"), BarColumn(), MofNCompleteColumn(), TimeElapsedColumn(),
             TextColumn("{task.description}"), console=err, transient=False) as bar:
        task = bar.add_task("", total=None)

        def update(done: int, total: int, row: dict) -> None:
            bar.update(task, completed=done, total=total,
                       description=f"last: run {row['run']} {row['status']}")
        yield update


@click.command()
@click.argument("file", type=click.Path(dir_okay=False, path_type=Path))
@click.option("--output", type=click.Path(file_okay=False, path_type=Path),
              default=Path("experiment-output"), show_default=True,
              help="Folder for results.csv, summary.md, plots and one folder per run.")
@click.option("--jobs", type=click.IntRange(min=1), default=None,
              show_default="one per CPU",
              help="Runs at once on this machine (each on its own private rendezvous).")
@click.option("--scheduler", metavar="tcp://HOST:PORT", default=None,
              help="Run every run as a task on this Dask cluster instead (workers started with "
                   "--resources runs=1; needs pip install 'mrta-zenoh[dask]').")
@click.option("--max-runs", type=click.IntRange(min=1), default=MAX_RUNS, show_default=True,
              help="Refuse a matrix of more runs than this (seeds × failures × overrides).")
def experiment(file: Path, output: Path, jobs: int | None, scheduler: str | None,
               max_runs: int) -> None:
    """Run the matrix of FILE (seeds × failures × parameter overrides) and summarise it."""
    with stop_on_signals() as stop, progress_reporter() as progress:
        rows = run_experiment(file=file, output=output, jobs=jobs, stop=stop, progress=progress,
                              scheduler=scheduler, max_runs=max_runs)
    failed = sum(r["status"] != "ok" for r in rows)
    click.echo(f"{plural(len(rows), 'run')} ({failed} failed): {output / 'results.csv'}, "
               f"{output / 'summary.md'}, {output / 'takeover.png'}, {output / 'coverage.png'}")
    click.echo((output / "summary.md").read_text())
    if failed:  # a sweep with holes is not a result: say so to scripts and CI (exit 1)
        raise MrtaRuntimeError(f"{failed} of {plural(len(rows), 'run')} failed: "
                               f"see {output / 'summary.md'}")
