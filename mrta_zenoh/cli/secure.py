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
              help="An observer (supervisor, recorder, viewer…): may only subscribe and "
                   "announce a recorder (repeatable).")
@click.option("--bridge", "bridges", multiple=True, metavar="ROBOT|NAME=ROBOT,…",
              help="A ROS 2 bridge (`mrta ros2 bridge`) for those robots only (repeatable); "
                   "named bridge-ROBOT unless NAME is given.")
@click.option("--submitter", "submitters", multiple=True, metavar="NAME",
              help="Who may submit tasks at run time (`mrta task … --as NAME`): only on "
                   "tasks/request/NAME (repeatable); adds the run's intake, `tasks`.")
@click.option("--process", "processes", multiple=True, metavar="NAME",
              help="An architecture's own process under the role its package registers "
                   "(central: --process dispatcher; only it may publish queues) (repeatable).")
@click.option("--endpoint", default=DEFAULT_ENDPOINT, show_default=True,
              help="Where the router listens (a tls/ endpoint); its certificate names this host.")
@click.option("--root", metavar="DIR",
              help="The folder's absolute path on the machines that use it (the configs name "
                   "the certificates there). Default: FOLDER's absolute path here.")
@click.option("--ros2-domain", type=click.IntRange(0, 232), default=0, show_default=True,
              envvar="ROS_DOMAIN_ID", show_envvar=True,
              help="The ROS_DOMAIN_ID of robots' and bridges' ROS 2 topics.")
@click.option("--no-simulator", is_flag=True, help="No certificate for a simulator.")
@click.option("--force", is_flag=True,
              help="Replace the files a previous `secure init` wrote in FOLDER (other files "
                   "there are left alone).")
def secure_init(folder: Path, robots: tuple[str, ...], observers: tuple[str, ...],
                bridges: tuple[str, ...], submitters: tuple[str, ...], processes: tuple[str, ...],
                endpoint: str, root: str | None, ros2_domain: int, no_simulator: bool,
                force: bool) -> None:
    """Write a CA, a certificate per process, router.json5 and one NAME.json5 per process."""
    files = init(folder, list(robots), list(observers), bridges=list(bridges),
                 submitters=list(submitters), processes=list(processes), endpoint=endpoint,
                 simulator=not no_simulator, force=force, root=root, ros2_domain=ros2_domain)
    names = sorted(p.stem for p in files if p.suffix == ".json5" and p.stem != "router")
    click.echo(f"wrote {plural(len(files), 'file')} to {folder}")
    click.echo(f"  router: mrta router --zenoh-config {folder / 'router.json5'}")
    click.echo(f"  others: mrta … --zenoh-config {folder}/NAME.json5 for NAME in "
               f"{', '.join(names)}")
    click.echo(f"  keep ca.key offline; copy the folder to {root or folder.resolve()} on each "
               "machine")
