"""`mrta replay`: a thin click wrapper over mrta_zenoh.tools.replay.run_replay."""

from __future__ import annotations

from pathlib import Path

import click

from ..bus import BusOptions
from ..tools.replay import MAX_GAP, run_replay
from .common import bus_options, finite_float


@click.command()
@click.argument("recording", type=click.Path(dir_okay=False, exists=True, path_type=Path))
@click.option("--speed", type=finite_float(min=0), default=1.0, show_default=True,
              help="Pace relative to the recording (0: as fast as possible).")
@click.option("--keys", "key_expr", default="**", show_default=True, metavar="EXPR",
              help="Only samples (and tokens) whose key matches this key expression.")
@click.option("--clock", is_flag=True, help="Republish the simulated clock too.")
@click.option("--max-gap", type=finite_float(min=0, min_open=True), default=MAX_GAP,
              show_default=True, metavar="SECONDS",
              help="Shorten a silence longer than this (recording seconds) to this.")
@bus_options
def replay(recording: Path, speed: float, key_expr: str, clock: bool, max_gap: float,
           bus_options: BusOptions) -> None:
    """Republish RECORDING's bus channels with their original timing (rosbag play).

    Records a session could not carry (a key like a//b or a wildcard, a malformed liveliness
    change) are skipped with a warning; silences longer than --max-gap are shortened."""
    run_replay(recording=recording, bus_options=bus_options, speed=speed, key_expr=key_expr,
               clock=clock, max_gap=max_gap)
