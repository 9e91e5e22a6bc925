"""`mrta plot KIND RECORDING …`: PNGs from an MCAP recording.

The kinds come from the `mrta.plots` entry points: the supervisor's `timeline` (any
architecture), ALLIANCE's `motivation`, and whatever an installed package adds.
"""

from __future__ import annotations

from pathlib import Path

import click

from mrta_zenoh.cli.common import OutputPath
from mrta_zenoh.cli.main import EntryPointGroup

from .api import resolve_application
from .plots import plot_timeline


class PlotGroup(EntryPointGroup):
    GROUP = "mrta.plots"


@click.group(cls=PlotGroup)
def plot() -> None:
    """Plots from a recording made with `mrta record` (or `mrta demo`)."""


@click.command()
@click.argument("recording", type=click.Path(dir_okay=False, exists=True, path_type=Path))
@click.option("--app", "app_spec", metavar="NAME|PATH",
              help="The application whose monitors read the recording (name or rqt_mrta.xml); "
                   "default: the only registered application.")
@click.option("-o", "--output", required=True, type=OutputPath(folder=False),
              help="The PNG to write.")
def timeline(recording: Path, app_spec: str | None, output: Path) -> None:
    """Which robot did which task when (a Gantt chart), with offline periods hatched."""
    app, arch = resolve_application(app_spec)
    plot_timeline(recording, app, arch, output)
    click.echo(f"wrote {output}")
