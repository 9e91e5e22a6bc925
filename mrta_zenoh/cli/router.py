"""`mrta router`: a Zenoh router for set-ups that span several machines.

Its options are not the other commands' bus options: a router is always a router (no --mode),
routes every key as it is (no --namespace), and listens by default on the rendezvous endpoint,
not on a random port — so every peer on this machine meets it with no configuration.
"""

from __future__ import annotations

from pathlib import Path

import click

from ..bus.options import RENDEZVOUS_ENV, BusOptions
from ..lifecycle import stop_on_signals


@click.command()
@click.option("--listen", "listen", multiple=True, metavar="ENDPOINT",
              help="Endpoint to listen on (repeatable). Default: the rendezvous endpoint, "
                   f"tcp/127.0.0.1:7447 (or ${RENDEZVOUS_ENV}); give tcp/0.0.0.0:7447 to "
                   "accept other machines.")
@click.option("--connect", "connect", multiple=True, metavar="ENDPOINT",
              help="Another router to connect to (repeatable).")
@click.option("--zenoh-config", type=click.Path(dir_okay=False, path_type=Path),
              metavar="FILE.json5",
              help="Zenoh configuration file (merged over our loopback defaults); its "
                   "listen endpoints replace the default.")
def router(listen: tuple[str, ...], connect: tuple[str, ...], zenoh_config: Path | None) -> None:
    """Run a Zenoh router, listening on the rendezvous endpoint unless told otherwise.

    For two machines, run `mrta router --listen tcp/0.0.0.0:7447` on one and give every other
    process `--connect tcp/ROUTER_IP:7447` (see the README).
    """
    from ..bus.zenoh_bus import run_router

    given = BusOptions(connect=list(connect), listen=list(listen), zenoh_config=zenoh_config)
    configured = (given.user_config().get("listen") or {}).get("endpoints")  # bad file: exit 2
    opts = BusOptions(mode="router", connect=given.connect,
                      listen=given.listen or ([] if configured else [given.rendezvous_endpoint]),
                      zenoh_config=zenoh_config)
    opts.check()  # Zenoh's own refusal of the file: exit 2 naming it, before anything starts
    with stop_on_signals() as stop:
        click.echo(f"router listening on {', '.join(opts.listen or configured)}", err=True)
        run_router(opts, stop)
