"""`mrta echo`: a thin click wrapper over mrta_zenoh.tools.echo.run_echo.

It takes what a ROS 2 user types: a topic name with its leading slash (`/robot1/odom` is the
key `robot1/odom`, as rmw_zenoh maps names to keys) and a dotted field path
(`header.frame_id`, beside variant_topic_tools' `header/frame_id`: mrta_zenoh.fieldpath)."""

from __future__ import annotations

import click

from ..bus import BusOptions
from ..fieldpath import FieldPath
from ..tools.echo import run_echo
from .common import bus_options


def key_of(topic: str) -> str:
    """A ROS topic name (`/robot1/odom`) as the key it names (`robot1/odom`); a key expression
    unchanged. Zenoh keys never start with '/', ROS names always do."""
    return topic[1:] if topic.startswith("/") and len(topic) > 1 else topic


@click.command(short_help="Print the samples on a key expression or ROS topic.")
@click.argument("key_expr")
@click.option("--field", "-f", metavar="PATH",
              help="Print only this field: header/frame_id, header.frame_id, points[0].x.")
@click.option("--count", "-n", type=click.IntRange(min=1), help="Exit after N samples.")
@click.option("--json", "as_json", is_flag=True, help="One JSON object per line.")
@bus_options
def echo(key_expr: str, field: str | None, count: int | None, as_json: bool,
         bus_options: BusOptions) -> None:
    """Print the samples on KEY_EXPR as they arrive, like `ros2 topic echo`.

    KEY_EXPR is a Zenoh key expression such as '*/alliance/inter_robot_communication' or
    'robot1/**'; a ROS topic name works too (/robot1/odom is the key robot1/odom).
    """
    key_expr = key_of(key_expr)
    if field:
        FieldPath.parse(field)  # bad input: before the session opens
    run_echo(bus_options=bus_options, key_expr=key_expr, field=field, count=count,
             as_json=as_json, emit=click.echo,
             warn=lambda text: click.echo(f"warning: {text}", err=True))
