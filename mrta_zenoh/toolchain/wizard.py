"""The new-application wizard in the terminal, in the dissertation's steps (§3.4, figures 3.6–3.12).

General data → architecture (with taxonomy filters) → robots and their tasks → every parameter
(tool_tip as help, defaults offered, mandatory ones insisted on, types checked, arrays sized by the
user) → a summary of exactly what will be written → confirm. It only *collects* answers; checking
and writing are the generator's, shared with `--answers`.
"""

from __future__ import annotations

from typing import Any, Callable

import click

from ..errors import ConfigError
from ..keys import is_id
from .generator import EMAIL, PACKAGE_NAME, VERSION, Answers
from .model import Architecture, Node, Param, Params
from .registry import Package, Registry, matches_taxonomy, taxonomy_value
from .templates import ARRAY_SIZE, TASK_PLACEHOLDER, convert


def _check(pattern, message: str) -> Callable[[str], str]:
    def proc(value: str) -> str:
        value = value.strip()
        if not pattern.match(value):
            raise click.UsageError(message)
        return value
    return proc


def _nonempty(what: str) -> Callable[[str], str]:
    def proc(value: str) -> str:
        if not value.strip():
            raise click.UsageError(f"{what} cannot be empty")
        return value.strip()
    return proc


def _csv(value: str) -> list[str]:
    return [v.strip() for v in value.split(",") if v.strip()]


def collect(registry: Registry, echo: Callable[[str], None] = click.echo) -> tuple[Answers, Package, Architecture]:
    echo(click.style("1/5 General data", bold=True))
    package = click.prompt("Package name (lower case, e.g. my_patrol)",
                           value_proc=_check(PACKAGE_NAME, "use lower-case letters, digits and '_', "
                                                           "starting with a letter"))
    name = click.prompt("Application name", value_proc=_nonempty("the name"))
    version = click.prompt("Version", default="1.0.0",
                           value_proc=_check(VERSION, "expected MAJOR.MINOR.PATCH, e.g. 1.0.0"))
    description = click.prompt("Description", default=name)
    maintainer = click.prompt("Maintainer", value_proc=_nonempty("the maintainer"))
    email = click.prompt("Maintainer e-mail", value_proc=_check(EMAIL, "not a valid e-mail address"))
    license_ = click.prompt("Licence", default="Apache-2.0")
    depends = _csv(click.prompt("Other dependencies (comma-separated)", default="",
                                show_default=False))

    echo(click.style("2/5 Architecture", bold=True))
    archs = registry.architectures()
    filters = {}
    for axis, options in (("robots", "ST/MT"), ("tasks", "SR/MR"), ("allocations", "IA/TA")):
        def proc(v: str, axis=axis) -> str | None:
            if not v.strip():
                return None
            try:
                return taxonomy_value(axis, v)
            except ConfigError as exc:
                raise click.UsageError(str(exc)) from None
        filters[axis] = click.prompt(f"Filter by {axis} type ({options}, empty for any)",
                                     default="", show_default=False, value_proc=proc)
    shown = [(p, a) for p, a in archs if matches_taxonomy(a, **filters)]
    if not shown:
        raise ConfigError("no registered architecture matches these filters "
                          f"(registered: {', '.join(p.name for p, _ in archs) or 'none'})")
    for i, (p, a) in enumerate(shown, 1):
        echo(f"  {i}. {p.name}: {a.name} [{a.taxonomy}]")

    def pick(v: str) -> tuple[Package, Architecture]:
        v = v.strip()
        if v.isdigit() and 1 <= int(v) <= len(shown):
            return shown[int(v) - 1]
        for p, a in shown:
            if v in (p.name, a.name):
                return p, a
        raise click.UsageError(f"choose 1-{len(shown)} or a name")
    arch_pkg, arch = click.prompt("Architecture", default="1", value_proc=pick)

    echo(click.style("3/5 Robots and tasks", bold=True))

    def ids(v: str) -> list[str]:
        out = _csv(v)
        if not out or not all(is_id(x) for x in out):
            raise click.UsageError("give one or more ids (letters, digits, '_', '-', '.'), "
                                   "comma-separated")
        if len(set(out)) != len(out):
            raise click.UsageError("ids must be unique")
        return out
    robot_ids = click.prompt("Robot ids (comma-separated)", value_proc=ids)
    task_ids = click.prompt("Task ids of the application (comma-separated)", value_proc=ids)
    robots: dict[str, list[str]] = {}
    for rid in robot_ids:
        def subset(v: str) -> list[str]:
            chosen = ids(v)
            bad = [t for t in chosen if t not in task_ids]
            if bad:
                raise click.UsageError(f"unknown task {bad[0]!r}; tasks are {', '.join(task_ids)}")
            return chosen
        robots[rid] = click.prompt(f"Tasks {rid} can do", default=",".join(task_ids),
                                   value_proc=subset)

    echo(click.style("4/5 Parameters", bold=True))
    configs: dict[str, Any] = {}
    for c in arch.configs:
        if c.id == arch.config_id:
            configs[c.id] = {}
            for rid, tasks in robots.items():
                echo(click.style(f"{rid}_{c.id}", underline=True))
                configs[c.id][rid] = _ask_children(c.children, f"{rid}", tasks)
        elif c.children:
            echo(click.style(c.id, underline=True))
            configs[c.id] = _ask_children(c.children, c.id, None)
    answers = Answers(package=package, name=name, architecture=arch_pkg.name, robots=robots,
                      configs=configs, version=version, description=description,
                      maintainer=maintainer, email=email, license=license_, depends=depends)
    return answers, arch_pkg, arch


def _ask_children(children: list[Node], path: str, tasks: list[str] | None) -> dict:
    out: dict[str, Any] = {}
    for child in children:
        if isinstance(child, Param):
            if child.value == ARRAY_SIZE or child.value == TASK_PLACEHOLDER:
                continue  # sized from the array below / filled from the robot's tasks
            if child.value and "@" not in child.value:
                continue  # fixed by the architecture
            out[child.name] = _ask_param(child, f"{path}/{child.name}")
        elif isinstance(child, Params):
            out[child.name] = _ask_children(child.children, f"{path}/{child.name}", tasks)
        else:
            key = child.name.replace("@index@", "")
            if tasks is not None and _has_task_id(child):
                count = len(tasks)
                labels = tasks
            else:
                count = click.prompt(f"{path}: how many {key} entries", type=click.IntRange(0, 1000))
                labels = [str(i) for i in range(count)]
            items = []
            for i in range(count):
                click.echo(f"  {child.name.replace('@index@', str(i))} ({labels[i]})")
                items.append(_ask_children(child.children, f"{path}/{key}{i}", tasks))
            out[key] = items
    return out


def _has_task_id(node: Node) -> bool:
    if isinstance(node, Param):
        return node.value == TASK_PLACEHOLDER
    return any(_has_task_id(c) for c in node.children)


def _ask_param(p: Param, path: str) -> Any:
    def proc(v: str) -> Any:
        if v == "" and not p.default:
            raise click.UsageError(f"{p.name} is mandatory")
        try:
            return convert(p.type, v if v != "" else p.default, path)
        except ConfigError as exc:
            raise click.UsageError(str(exc)) from None
    help_ = f" — {p.tool_tip}" if p.tool_tip else ""
    return click.prompt(f"{path} [{p.type or 'string'}]{help_}",
                        default=p.default if p.default else None, value_proc=proc)


def summary(answers: Answers, arch: Architecture, files: dict[str, bytes], dest) -> str:
    lines = [f"Application {answers.name!r} ({arch.name}, {arch.taxonomy}) → {dest}",
             "Robots: " + "; ".join(f"{r}: {', '.join(t)}" for r, t in answers.robots.items()),
             "Files:"]
    lines += [f"  {rel} ({len(data)} bytes)" for rel, data in sorted(files.items())]
    return "\n".join(lines)

