"""`mrta router`: a Zenoh router for set-ups that span several machines."""

from __future__ import annotations

import click

from ..bus.options import BusOptions
from ..lifecycle import stop_on_signals
from .common import bus_options


@click.command()
@bus_options
def router(bus_options: BusOptions) -> None:
    """Run a Zenoh router (default: listen on the rendezvous endpoint, tcp/127.0.0.1:7447).

    For two machines, run `mrta router --listen tcp/0.0.0.0:7447` on one and give every other
    process `--connect tcp/ROUTER_IP:7447` (see the README).
    """
    from ..bus.zenoh_bus import run_router

    configured = (bus_options.user_config().get("listen") or {}).get("endpoints")
    opts = BusOptions(mode="router", connect=bus_options.connect,
                      listen=bus_options.listen or ([] if configured else
                                                    [bus_options.rendezvous_endpoint]),
                      zenoh_config=bus_options.zenoh_config)
    with stop_on_signals() as stop:
        click.echo(f"router listening on {', '.join(opts.listen or configured)}", err=True)
        run_router(opts, stop)
