"""`mrta echo`: a thin click wrapper over mrta_zenoh.tools.echo.run_echo."""

from __future__ import annotations

import click

from ..bus import BusOptions
from ..fieldpath import FieldPath
from ..tools.echo import run_echo
from .common import bus_options


@click.command()
@click.argument("key_expr")
@click.option("--field", "-f", metavar="PATH", help="Print only this field, e.g. header/frame_id.")
@click.option("--count", "-n", type=click.IntRange(min=1), help="Exit after N samples.")
@click.option("--json", "as_json", is_flag=True, help="One JSON object per line.")
@bus_options
def echo(key_expr: str, field: str | None, count: int | None, as_json: bool,
         bus_options: BusOptions) -> None:
    """Print samples on KEY_EXPR (e.g. '*/alliance/inter_robot_communication') as they arrive."""
    if field:
        FieldPath.parse(field)  # bad input: before the session opens
    run_echo(bus_options=bus_options, key_expr=key_expr, field=field, count=count,
             as_json=as_json, emit=click.echo,
             warn=lambda text: click.echo(f"warning: {text}", err=True))
