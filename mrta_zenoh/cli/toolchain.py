"""`mrta arch …`, `mrta app …` and `mrta launch`: thin wrappers over mrta_zenoh.toolchain."""

from __future__ import annotations

import json
import shlex
from pathlib import Path
from typing import Callable, TypeVar

import click

from ..errors import ConfigError, Interrupted, MrtaRuntimeError
from ..lifecycle import interrupted_by_user, stop_on_signals
from ..toolchain.checks import PackageRefused, check_package_files, check_robot_files
from ..toolchain.generator import build_application, load_answers, restrict_layers, write_package
from ..toolchain.launchfile import LaunchEvaluator, check_executables
from ..toolchain.missionfiles import mission_files, mission_launch, registered_missions
from ..toolchain.model import ApplicationFile, ArchitectureFile, Array, Param, Params
from ..toolchain.registry import Registry, matches_taxonomy, taxonomy_value
from ..toolchain.runner import command_for, run_nodes
from ..files import write_text
from ..toolchain.wizard import (InvalidAnswer, Transcript, ask_again, collect, load_transcript,
                                summary, transcript_yaml)
from ..toolchain.xmlio import load_rqt_mrta
from .common import plural

T = TypeVar("T")


def _problems(reg: Registry) -> None:
    for p in reg.problems:
        click.echo(f"warning: {p}", err=True)


@click.group()
def arch() -> None:
    """Registered MRTA architectures (rqt_mrta's plugins)."""


@arch.command("list")
@click.option("--robots", help="ST (single-task) or MT (multi-task) robots.")
@click.option("--tasks", help="SR (single-robot) or MR (multi-robot) tasks.")
@click.option("--allocations", help="IA (instantaneous) or TA (time-extended) assignment.")
@click.option("--json", "as_json", is_flag=True, help="One JSON object per architecture.")
def arch_list(robots: str | None, tasks: str | None, allocations: str | None, as_json: bool) -> None:
    """List architectures, filtered by the Gerkey–Matarić taxonomy."""
    f = {k: taxonomy_value(k, v) if v else None
         for k, v in (("robots", robots), ("tasks", tasks), ("allocations", allocations))}
    reg = Registry()
    rows = [(p, a) for p, a in reg.architectures() if matches_taxonomy(a, **f)]
    _problems(reg)
    for p, a in rows:
        if as_json:
            click.echo(json.dumps({"package": p.name, "name": a.name, "taxonomy": a.taxonomy,
                                   "file": str(p.architecture_file), "origin": p.origin}))
        else:
            click.echo(f"{p.name:20} {a.name:20} {a.taxonomy:10} {p.origin}")


def _show_params(children, indent: int) -> list[str]:
    out = []
    for c in children:
        pad = "  " * indent
        if isinstance(c, Param):
            extra = f" = {c.value}" if c.value else (f" (default {c.default})" if c.default else
                                                      " (mandatory)")
            out.append(f"{pad}{c.name}: {c.type or 'string'}{extra}")
        elif isinstance(c, (Params, Array)):
            out.append(f"{pad}{c.name}{'[]' if isinstance(c, Array) else ''}:")
            out += _show_params(c.children, indent + 1)
    return out


def _describe(model: ArchitectureFile | ApplicationFile) -> list[str]:
    if isinstance(model, ArchitectureFile):
        lines = [f"architecture {model.name} [{model.taxonomy}]"]
        for label in ("busy_robots", "idle_robots", "incoming_tasks", "allocated_tasks"):
            t = getattr(model, label)
            if t:
                lines.append(f"  {label}: {t.name} ({t.type}) field {t.field}, "
                             f"timeout {t.timeout} s, queue {t.queue_size}")
        lines.append(f"  per-robot config: {model.config_id}; launch: {model.launch_id}")
    else:
        lines = [f"application {model.name} (architecture {model.architecture})"]
        for r in model.robots:
            lines.append(f"  {r.id}: {', '.join(r.tasks)}")
    for c in model.configs:
        lines.append(f"  config {c.id}:")
        lines += _show_params(c.children, 2)
    for la in model.launches:
        lines.append(f"  launch {la.id}: " + ", ".join(i.file for i in la.includes))
    return lines


@arch.command("show")
@click.argument("name")
def arch_show(name: str) -> None:
    """Show an architecture: taxonomy, monitors, config templates, launches."""
    pkg, a = Registry().architecture(name)
    click.echo(f"package {pkg.name} {pkg.version} at {pkg.path}")
    click.echo("\n".join(_describe(a)))


_KIND = {ArchitectureFile: "architecture", ApplicationFile: "application"}


def _validate(path: Path, kind: type) -> None:
    """PATH is an rqt_mrta.xml file, a package folder holding one, or a registered package's
    name. An application's architecture must also be registered: a package naming an
    architecture nobody installed would validate, then fail at launch."""
    if path.is_dir():
        path = path / "rqt_mrta.xml"
    elif not path.exists() and len(path.parts) == 1:
        reg = Registry()
        if path.name in reg.packages:
            path = reg.find(path.name).path / "rqt_mrta.xml"
    model = load_rqt_mrta(path)
    if not isinstance(model, kind):
        raise ConfigError(f"this is an {_KIND[type(model)]} file, not an {_KIND[kind]} file",
                          file=str(path))
    checked = []
    if isinstance(model, ApplicationFile):
        Registry().architecture_of(model)
        checked = check_robot_files(path.parent, model)
    click.echo(f"{path}: valid {_KIND[kind]} {model.name!r}"
               + (f" (the parameter files of {plural(len(checked), 'robot')} checked)"
                  if checked else ""))


@arch.command("validate")
@click.argument("path", type=click.Path(path_type=Path))
def arch_validate(path: Path) -> None:
    """Check an architecture (file, package folder or package name); exit 2 naming file, line
    and element on the first error."""
    _validate(path, ArchitectureFile)


@click.group()
def app() -> None:
    """Registered MRTA applications; create new ones."""


@app.command("list")
@click.option("--json", "as_json", is_flag=True)
def app_list(as_json: bool) -> None:
    """List applications found on MRTA_PACKAGE_PATH, in configs/ and through entry points."""
    reg = Registry()
    rows = reg.applications()
    _problems(reg)
    for p, a in rows:
        if as_json:
            click.echo(json.dumps({"package": p.name, "name": a.name, "architecture": a.architecture,
                                   "robots": [r.id for r in a.robots], "path": str(p.path)}))
        else:
            click.echo(f"{p.name:20} {a.name:30} {a.architecture:12} "
                       f"{plural(len(a.robots), 'robot'):9} {p.path}")


@app.command("show")
@click.argument("name")
def app_show(name: str) -> None:
    """Show an application: robots and their tasks, configs, launches."""
    pkg, a = Registry().application(name)
    click.echo(f"package {pkg.name} {pkg.version} at {pkg.path}")
    click.echo("\n".join(_describe(a)))


@app.command("validate")
@click.argument("path", type=click.Path(path_type=Path))
def app_validate(path: Path) -> None:
    """Check an application (file, package folder or package name); exit 2 naming file, line
    and element on the first error."""
    _validate(path, ApplicationFile)


RESUME_FILE = "mrta_app_new_answers.yaml"  # an interrupted wizard's answers (app_new --resume)


@app.command("new")
@click.option("--answers", type=click.Path(dir_okay=False, path_type=Path),
              help="YAML answers instead of prompts (docs/toolchain.md).")
@click.option("--output", type=click.Path(file_okay=False, path_type=Path), default=Path("."),
              show_default=True, help="Folder in which the package folder is created.")
@click.option("--force", is_flag=True, help="Replace an existing package folder.")
@click.option("--yes", is_flag=True, help="Do not ask for confirmation after the summary.")
@click.option("--resume", type=click.Path(dir_okay=False, exists=True, path_type=Path),
              help="The answers an interrupted session wrote (Ctrl-C writes "
                   f"OUTPUT/{RESUME_FILE}): given again, only the rest is asked.")
def app_new(answers: Path | None, output: Path, force: bool, yes: bool,
            resume: Path | None) -> None:
    """Create an application package: general data, architecture, robots, parameters, summary.

    Nothing is written that `mrta app validate` would refuse: the generated files are first
    read by the architecture as its agents will read them; the wizard then asks again for the
    answers behind a refused file, an answers file is refused naming its line."""
    reg = Registry()
    if answers is not None:
        a, doc = load_answers(answers)
        arch_pkg, arch_model = reg.architecture(a.architecture)
        arch_model = restrict_layers(arch_pkg, arch_model, a, doc)
        app, files = build_application(arch_pkg, arch_model, a, doc)
        checked = check_package_files(files, app, doc)
    else:
        ui = Transcript(TerminalPrompter(), load_transcript(resume) if resume else None)
        try:
            a, arch_pkg, arch_model = collect(reg, ui)
            while True:
                app, files = build_application(arch_pkg, arch_model, a)
                try:
                    checked = check_package_files(files, app)
                    break
                except PackageRefused as exc:
                    click.echo(click.style(f"Error: {exc}", fg="red"), err=True)
                    ask_again(ui, a, arch_model, exc.generated)
        except click.Abort:  # Ctrl-C (or the end of input) at a prompt: keep what was said
            if ui.said:
                kept = write_text(output / RESUME_FILE, transcript_yaml(ui.said))
                click.echo(f"\n{plural(len(ui.said), 'answer')} kept in {kept}: "
                           f"`mrta app new --resume {kept}` asks only the rest", err=True)
            raise
    files.update(mission_files(app, a.package, a.mission, files, reg))
    dest = output / a.package
    if dest.exists() and not force:
        raise ConfigError(f"{dest} already exists; use --force to replace it")
    click.echo(click.style("5/5 Summary", bold=True) if answers is None else "Summary")
    click.echo(summary(a, arch_model, files, dest))
    if not checked:
        click.echo(f"(the parameter files are not checked: no contract for architecture "
                   f"{arch_pkg.name!r} is registered under mrta.architectures)")
    if answers is None and not yes and not click.confirm("Write these files?", default=True):
        raise click.ClickException("nothing written")
    write_package(files, dest, force)
    click.echo(f"wrote {plural(len(files), 'file')} to {dest}")
    click.echo(next_steps(a.package, output, files, a.mission))


def next_steps(package: str, output: Path, files: dict[str, bytes], mission: str) -> str:
    """What to do with the new package — the wizard ended saying nothing (issue 51, the
    newcomer's list). Each line works as printed (tests/test_toolchain_wizard.py): its launch
    files find it by name (`$(find PKG)`), so it must be on MRTA_PACKAGE_PATH or installed;
    `mrta demo` runs it when it was made for a mission (its simulation launch file derived
    from the mission's, toolchain/missionfiles.py), and the last line says how to make it so
    when it was not."""
    where = shlex.quote(str(output))
    main = f"{package}.launch" if f"launch/{package}.launch" in files else "FILE.launch"
    runs = bool(mission) and f"launch/{mission_launch(mission)}" in files
    return "\n".join([
        "next:",
        f"  MRTA_PACKAGE_PATH={where} mrta app show {package}      # found by name there "
        "(or pip-install it: README, \"Your own application\")",
        f"  MRTA_PACKAGE_PATH={where} mrta launch {package} {main}   # every robot's agent; "
        "their world: `mrta sim` (README, \"The mission in separate terminals\")",
        f"  MRTA_PACKAGE_PATH={where} mrta demo --application {package}   # the {mission} "
        "mission with these robots: simulator, agents, summary" if runs else
        "  `mrta demo` runs an application made for a mission: answer the wizard's mission "
        f"question ({', '.join(registered_missions()) or 'none installed'}), or give "
        "`mission:` in an answers file"])


class TerminalPrompter:
    """The wizard's questions on the terminal (mrta_zenoh.toolchain.wizard.Prompter): click's
    prompts, asking again — with the reason — until an answer is accepted."""

    def step(self, title: str) -> None:
        click.echo(click.style(title, bold=True))

    def section(self, title: str) -> None:
        click.echo(click.style(title, underline=True))

    def say(self, text: str) -> None:
        click.echo(text)

    def ask(self, question: str, check: Callable[[str], T], default: str | None = None,
            show_default: bool = True) -> T:
        def proc(value: str) -> T:
            try:
                return check(value)
            except InvalidAnswer as exc:  # click.prompt says it and asks again
                raise click.UsageError(str(exc)) from None
        if default is None:  # click would ask again after an empty answer, saying nothing:
            default, show_default = "", False  # `check` says why it needs one
        return click.prompt(question, default=default, show_default=show_default,
                            value_proc=proc)


def _split_launch_args(items: tuple[str, ...]) -> dict[str, str]:
    out = {}
    for item in items:
        name, sep, value = item.partition(":=")
        if not sep or not name:
            raise ConfigError(f"launch argument {item!r}: expected name:=value")
        out[name] = value
    return out


@click.command()
@click.argument("target")
@click.argument("rest", nargs=-1)
@click.option("--dry-run", is_flag=True, help="Print the commands that would run, one per node.")
def launch(target: str, rest: tuple[str, ...], dry_run: bool) -> None:
    """Run a launch file: `mrta launch PACKAGE FILE.launch [name:=value …]` or a path.

    Every node starts as a child process with its output prefixed by the node's name. As in
    roslaunch, a node that ends is reported at once (exit code, or the signal that killed it);
    a required="true" node that ends stops them all, as does Ctrl-C. Exit 1 if a node failed,
    130 on Ctrl-C.
    """
    reg = Registry()
    path = Path(target)
    if path.suffix == ".launch" and path.is_file():
        args = rest
    else:
        if not rest:
            raise ConfigError(f"{target!r} is not a launch file; give PACKAGE FILE.launch")
        pkg = reg.find(target)
        path = pkg.path / "launch" / rest[0]
        if not path.is_file():
            found = sorted(p.name for p in (pkg.path / "launch").glob("*.launch"))
            raise ConfigError(f"package {pkg.name} has no launch/{rest[0]} "
                              f"(it has: {', '.join(found) or 'none'})")
        args = rest[1:]
    nodes = LaunchEvaluator(lambda name: reg.find(name).path).run(path, _split_launch_args(args))
    check_executables(nodes)
    if dry_run:
        for n in nodes:
            env = "".join(f"{k}={shlex.quote(v)} " for k, v in n.env.items())
            click.echo(f"[{n.name}] {env}{shlex.join(command_for(n))}")
        return
    with stop_on_signals() as stop:
        result = run_nodes(nodes, stop, echo=lambda line: click.echo(line),
                           notify=lambda line: click.echo(line, err=True))
    if result.interrupted and interrupted_by_user():  # Ctrl-C: 130; SIGTERM: a clean stop
        raise Interrupted()
    if result.failed:
        raise MrtaRuntimeError(f"{plural(len(result.failed), 'node')} failed: "
                               + "; ".join(result.failed))



