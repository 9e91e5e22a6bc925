"""`mrta experiment FILE.yaml`: a thin click wrapper over mrta_supervisor.experiment."""

from __future__ import annotations

from pathlib import Path

import click
from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn

from mrta_zenoh.cli.common import plural
from mrta_zenoh.errors import MrtaRuntimeError
from mrta_zenoh.lifecycle import stop_on_signals

from .experiment import run_experiment


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
def experiment(file: Path, output: Path, jobs: int | None, scheduler: str | None) -> None:
    """Run the matrix of FILE (seeds × failures × parameter overrides) and summarise it."""
    with stop_on_signals() as stop, Progress(
            TextColumn("[bold]runs"), BarColumn(), MofNCompleteColumn(), TimeElapsedColumn(),
            TextColumn("{task.description}"), transient=False) as bar:
        task = bar.add_task("", total=None)

        def progress(done: int, total: int, row: dict) -> None:
            bar.update(task, completed=done, total=total,
                       description=f"last: run {row['run']} {row['status']}")

        rows = run_experiment(file=file, output=output, jobs=jobs, stop=stop, progress=progress,
                              scheduler=scheduler)
    failed = sum(r["status"] != "ok" for r in rows)
    click.echo(f"{plural(len(rows), 'run')} ({failed} failed): {output / 'results.csv'}, "
               f"{output / 'summary.md'}, {output / 'takeover.png'}, {output / 'coverage.png'}")
    click.echo((output / "summary.md").read_text())
    if failed:  # a sweep with holes is not a result: say so to scripts and CI (exit 1)
        raise MrtaRuntimeError(f"{failed} of {plural(len(rows), 'run')} failed: "
                               f"see {output / 'summary.md'}")
