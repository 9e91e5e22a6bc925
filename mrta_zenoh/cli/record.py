"""`mrta record`: a thin click wrapper over mrta_zenoh.tools.record.run_record."""

from __future__ import annotations

import faulthandler
import sys
from pathlib import Path

import click

from ..bus import BusOptions
from ..tools.record import run_record
from .common import bus_options, finite_float


@click.command()
@click.option("-o", "--output", required=True, type=click.Path(dir_okay=False, path_type=Path),
              help="The MCAP file to write.")
@click.argument("key_exprs", nargs=-1)
@click.option("--duration", type=finite_float(min=0, min_open=True),
              help="Stop after this many (wall) seconds.")
@click.option("--sim-time", is_flag=True,
              help="Log times are the simulator's time, so the file plays at mission speed "
                   "whatever the run's --speed.")
@click.option("--dated", is_flag=True,
              help="With --sim-time: log times start at the wall-clock time the run's clock "
                   "was first heard, so viewers show the run's date; durations stay simulated.")
@bus_options
def record(output: Path, key_exprs: tuple[str, ...], duration: float | None, sim_time: bool,
           dated: bool, bus_options: BusOptions) -> None:
    """Record every sample on KEYEXPR… (default: everything) to an MCAP file."""
    if sys.__stderr__ is not None:  # a native crash (zenoh, msgspec, mcap) leaves its stacks
        faulthandler.enable(sys.__stderr__)
    run_record(output=output, key_exprs=list(key_exprs) or ["**"], bus_options=bus_options,
               duration=duration, sim_time=sim_time, dated=dated)
