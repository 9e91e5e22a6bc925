"""`mrta instance generate | show | validate`: thin click wrappers over mrta_zenoh.instances.

`generate NAME` has one subcommand per registered generator, its options made from the fields of
the generator's `Params` (a msgspec Struct: type, default and `Meta(description=…)` as help), so a
generator brings no command-line code of its own.
"""

from __future__ import annotations

import json
import typing
from pathlib import Path

import click
import msgspec

from .. import instances

SKIP = {"seed"}  # every generator's option, declared once below


def _option(field: msgspec.structs.FieldInfo) -> click.Option:
    kind, help_text = field.type, ""
    if typing.get_origin(kind) is typing.Annotated:
        kind, *metas = typing.get_args(kind)
        help_text = " ".join(m.description for m in metas
                             if isinstance(m, msgspec.Meta) and m.description)
    nargs, base = 1, kind
    if typing.get_origin(kind) is tuple:
        args = typing.get_args(kind)
        nargs, base = len(args), args[0]
        if typing.get_origin(base) is typing.Annotated:
            base = typing.get_args(base)[0]
    default = field.default if field.default is not msgspec.NODEFAULT else None
    return click.Option([f"--{field.name.replace('_', '-')}", field.name],
                        type={int: int, float: float}.get(base, str), nargs=nargs,
                        default=default, show_default=default is not None,
                        required=field.default is msgspec.NODEFAULT and
                        field.default_factory is msgspec.NODEFAULT,
                        help=help_text or None)


def _generator_command(name: str, gen: instances.InstanceGenerator) -> click.Command:
    def callback(seed: int, output: Path | None, **options) -> None:
        options = {k: list(v) if isinstance(v, tuple) else v for k, v in options.items()
                   if v is not None}
        text = instances.generate(name, options, seed, output)
        if output is None:
            click.echo(text, nl=False)
        else:
            click.echo(f"wrote {output}", err=True)

    params = [_option(f) for f in msgspec.structs.fields(gen.Params) if f.name not in SKIP]
    params += [click.Option(["--seed"], type=int, default=0, show_default=True,
                            help="The instance's own seed (not a run's): same seed, same file."),
               click.Option(["-o", "--output"], type=click.Path(dir_okay=False, path_type=Path),
                            help="The file to write (default: standard output).")]
    doc = (type(gen).__doc__ or f"The {name} generator.").strip().split("\n\n")[0]
    return click.Command(name, callback=callback, params=params, help=doc,
                         short_help=doc.splitlines()[0])


class GeneratorGroup(click.Group):
    def list_commands(self, ctx: click.Context) -> list[str]:
        return sorted(instances.generators())

    def get_command(self, ctx: click.Context, name: str) -> click.Command | None:
        gens = instances.generators()
        return _generator_command(name, gens[name]) if name in gens else None


@click.group()
def instance() -> None:
    """Problem instances: generate them, look at them, check them (`mrta demo --instance`)."""


@instance.group(cls=GeneratorGroup)
def generate() -> None:
    """Write an instance with a registered generator (mrta.instances)."""


APPLICATION = click.option("--application", help="Read FILE as this application's instance "
                           "(default: its `application:` key, or the only one registered).")


@instance.command()
@click.argument("file", type=click.Path(exists=True, dir_okay=False, path_type=Path))
@APPLICATION
@click.option("--exact-limit", type=click.IntRange(min=0), default=10, show_default=True,
              help="Solve exactly up to this many tasks; above it, the best routes found.")
@click.option("--solutions", type=click.IntRange(min=1), default=None,
              help="The routing search's budget: accepted solutions (the same on any machine). "
                   "Default: a run's, 200, so this reference is the one its summary uses.")
@click.option("--time-limit", type=click.FloatRange(min=0, min_open=True), default=30.0,
              show_default=True, help="The routing search's safety cap, seconds per objective "
                                      "(a search it stops depends on the machine's speed).")
@click.option("--json", "as_json", is_flag=True, help="One JSON object.")
def show(file: Path, application: str | None, exact_limit: int, solutions: int | None,
         time_limit: float, as_json: bool) -> None:
    """Sizes, the cost matrix's summary and the reference values of an instance file."""
    info = instances.show(file, application, exact_limit=exact_limit, time_limit=time_limit,
                          solutions=solutions)
    if as_json:
        click.echo(json.dumps(info))
        return
    for key, value in info.items():
        if isinstance(value, dict):
            click.echo(f"{key}:")
            for k, v in value.items():
                if isinstance(v, dict):
                    v = ", ".join(f"{a}: {b}" for a, b in v.items())
                click.echo(f"  {k}: {v}")
        else:
            click.echo(f"{key}: {value}")


@instance.command()
@click.argument("file", type=click.Path(exists=True, dir_okay=False, path_type=Path))
@APPLICATION
def validate(file: Path, application: str | None) -> None:
    """Check an instance file: exit 0 if good, else 2 naming file, line and key."""
    loaded = instances.load(file, application)
    click.echo(f"{file}: ok ({loaded.kind.application} instance {loaded.name!r})")
