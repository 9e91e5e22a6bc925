"""`python -m mrta_delivery.generate_cli`: a thin click program over generate.py (the toolchain's
error translation and exit codes, like every mrta verb)."""

from __future__ import annotations

import sys
from pathlib import Path

import click

from mrta_zenoh.cli.common import SEED_TYPE, OutputPath, finite_float
from mrta_zenoh.cli.main import run

from .generate import HERE, INSTANCE, generate, load_instance, with_poisson_arrivals


@click.command()
@click.option("--instance", type=click.Path(dir_okay=False, exists=True, path_type=Path),
              default=INSTANCE, show_default=True)
@click.option("--output", type=OutputPath(folder=True), default=HERE.parent,
              help="Folder receiving NAME/, NAME_murdoch/, NAME_central/ and "
                   "NAME_central_answers.yaml (default: beside this package, i.e. regenerate "
                   "the shipped ones).")
@click.option("--name", default="delivery", show_default=True,
              help="Package names: NAME (ALLIANCE), NAME_murdoch and NAME_central; another "
                   "name than delivery makes them depend on delivery, whose mission they run.")
@click.option("--arrivals", type=click.Choice(["static", "poisson"]), default="static",
              show_default=True)
@click.option("--rate", type=finite_float(min=0, min_open=True), default=0.1, show_default=True,
              help="Poisson arrivals: tasks per second.")
@click.option("--seed", type=SEED_TYPE, default=0, show_default=True,
              help="Poisson arrivals: their seed.")
def main(instance: Path, output: Path, name: str, arrivals: str, rate: float,
         seed: int) -> None:
    """Write the delivery application packages (ALLIANCE, MURDOCH, central) from one
    instance."""
    params = load_instance(instance)
    if arrivals == "poisson":
        params = with_poisson_arrivals(params, rate, seed)
    written = generate(params, output, name)
    click.echo(f"wrote {len(written)} files under {output}")


if __name__ == "__main__":
    sys.exit(run(main, prog_name="python -m mrta_delivery.generate_cli"))
