"""`mrta plot KIND RECORDING …`: PNGs from an MCAP recording.

The kinds come from the `mrta.plots` entry points: the supervisor's `timeline` (any
architecture), ALLIANCE's `motivation`, and whatever an installed package adds.
"""

from __future__ import annotations

from pathlib import Path

import click

from mrta_zenoh.cli.common import OutputPath
from mrta_zenoh.cli.main import EntryPointGroup

from ..live.api import resolve_application
from .plots import VIEWS, plot_timeline
from .hook import application_watch


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
@click.option("--view", type=click.Choice(VIEWS), default="robots", show_default=True,
              help="robots: what the robots said they did (the demo summary's ground truth); "
                   "supervisor: what the supervisor showed (it lags by its monitors' "
                   "timeouts); both: one above the other.")
def timeline(recording: Path, app_spec: str | None, output: Path, view: str) -> None:
    """Which robot did which task when (a Gantt chart), with offline periods hatched."""
    app, arch = resolve_application(app_spec)
    watch = application_watch(app) if view != "robots" else None
    plot_timeline(recording, app, arch, output, view, watch)
    click.echo(f"wrote {output}")
