"""`mrta secure init`: a thin click wrapper over mrta_zenoh.secure.init."""

from __future__ import annotations

from pathlib import Path

import click

from ..secure import DEFAULT_ENDPOINT, init
from .common import plural


@click.group()
def secure() -> None:
    """Authenticated, authorised fleets: certificates and Zenoh configs (docs/security.md)."""


@secure.command("init")
@click.argument("folder", type=click.Path(file_okay=False, path_type=Path))
@click.option("--robot", "robots", multiple=True, metavar="ID",
              help="A robot: may publish only under ID/** (repeatable).")
@click.option("--observer", "observers", multiple=True, metavar="NAME",
              help="An observer (supervisor, recorder…): may only subscribe (repeatable).")
@click.option("--endpoint", default=DEFAULT_ENDPOINT, show_default=True,
              help="Where the router listens (a tls/ endpoint).")
@click.option("--no-simulator", is_flag=True, help="No certificate for a simulator.")
@click.option("--force", is_flag=True, help="Replace the files of a non-empty FOLDER.")
def secure_init(folder: Path, robots: tuple[str, ...], observers: tuple[str, ...], endpoint: str,
                no_simulator: bool, force: bool) -> None:
    """Write a CA, a certificate per process, router.json5 and one NAME.json5 per process."""
    files = init(folder, list(robots), list(observers), endpoint=endpoint,
                 simulator=not no_simulator, force=force)
    names = sorted(p.stem for p in files if p.suffix == ".json5" and p.stem != "router")
    click.echo(f"wrote {plural(len(files), 'file')} to {folder}")
    click.echo(f"  router: mrta router --zenoh-config {folder / 'router.json5'}")
    click.echo(f"  others: mrta … --zenoh-config {folder}/NAME.json5 for NAME in "
               f"{', '.join(names)}")
