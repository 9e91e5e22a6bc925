"""`mrta plot motivation`: a thin click verb over mrta_agent.alliance.plots.plot_motivation,
registered under the `mrta.plots` entry points."""

from __future__ import annotations

from pathlib import Path

import click
from mrta_zenoh.cli.common import OutputPath

from .plots import plot_motivation


@click.command()
@click.argument("recording", type=click.Path(dir_okay=False, exists=True, path_type=Path))
@click.option("--robot", required=True)
@click.option("--task", required=True)
@click.option("-o", "--output", required=True, type=OutputPath(folder=False))
def motivation(recording: Path, robot: str, task: str, output: Path) -> None:
    """rqt_alliance's seven panels for one robot and task, over time."""
    plot_motivation(recording, robot, task, output)
    click.echo(f"wrote {output}")
