"""`mrta plot motivation|timeline RECORDING …`: PNGs from an MCAP recording."""

from __future__ import annotations

from pathlib import Path

import click

from mrta_zenoh.cli.common import user_errors

from .cli import resolve_application
from .plots import plot_motivation, plot_timeline


@click.group()
def plot() -> None:
    """Plots from a recording made with `mrta record`."""


@plot.command()
@click.argument("recording", type=click.Path(dir_okay=False, exists=True, path_type=Path))
@click.option("--robot", required=True)
@click.option("--task", required=True)
@click.option("-o", "--output", required=True, type=click.Path(dir_okay=False, path_type=Path))
def motivation(recording: Path, robot: str, task: str, output: Path) -> None:
    """rqt_alliance's seven panels for one robot and task, over time."""
    with user_errors():
        plot_motivation(recording, robot, task, output)
    click.echo(f"wrote {output}")


@plot.command()
@click.argument("recording", type=click.Path(dir_okay=False, exists=True, path_type=Path))
@click.option("--app", "app_spec", default="patrol", show_default=True,
              help="The application whose monitors read the recording (name or rqt_mrta.xml).")
@click.option("-o", "--output", required=True, type=click.Path(dir_okay=False, path_type=Path))
def timeline(recording: Path, app_spec: str, output: Path) -> None:
    """Which robot did which task when (a Gantt chart), with offline periods hatched."""
    with user_errors():
        app, arch = resolve_application(app_spec)
        plot_timeline(recording, app, arch, output)
    click.echo(f"wrote {output}")
