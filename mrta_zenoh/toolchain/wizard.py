"""The new-application wizard in the terminal, in the dissertation's steps (§3.4, figures 3.6–3.12).

General data → architecture (with taxonomy filters) → robots and their tasks → every parameter
(tool_tip as help, defaults offered, mandatory ones insisted on, types checked, arrays sized by the
user) → a summary of exactly what will be written → confirm. It only *collects* answers; checking
and writing are the generator's, shared with `--answers`. The talking is a Prompter's: the
terminal's lives in the CLI layer, so this module knows no terminal.

Two departures from the dissertation's wizard, both so that it never writes what `mrta app
validate` refuses: the layers file's sections are asked for only when a plugin of the robots
reads them (generator.restrict_layers), and when the architecture refuses a generated file
(checks.check_package_files), `ask_again` asks for that file's answers once more — the earlier
answers offered as defaults — instead of ending the session.
"""

from __future__ import annotations

from typing import Any, Callable, Protocol, TypeVar

from ..errors import ConfigError
from ..keys import is_id
from .checks import PackageRefused, check_package_files, layers_config_id
from .missionfiles import check_mission, check_pairing, registered_missions
from .generator import (EMAIL, PACKAGE_NAME, VERSION, Answers, restrict_layers,
                        without_layers)
from .model import ApplicationFile, ArchitectureFile, Node, Param, Params, RobotEntry
from .registry import Package, Registry, matches_taxonomy, taxonomy_value
from .templates import ARRAY_SIZE, MAX_ITEMS, TASK_PLACEHOLDER, convert

T = TypeVar("T")


class InvalidAnswer(ConfigError):
    """An answer the wizard cannot take; a prompter asks again, saying why (the message).
    A ConfigError, so answers that cannot be asked again (a script) end as bad input."""


class Prompter(Protocol):
    """How the wizard talks to its user, so that it holds no terminal code: the terminal's
    prompter is the CLI's (mrta_zenoh.cli.toolchain); a test or a GUI brings its own."""

    def step(self, title: str) -> None:
        """A new step of the wizard ("1/5 General data")."""

    def section(self, title: str) -> None:
        """A group of questions within a step (one config file)."""

    def say(self, text: str) -> None:
        """A line of information (the architectures to choose from)."""

    def ask(self, question: str, check: Callable[[str], T], default: str | None = None,
            show_default: bool = True) -> T:
        """The checked answer to `question`: an empty answer means `default` when there is
        one; `check` turns the text into the value or raises InvalidAnswer."""


def _check(pattern, message: str) -> Callable[[str], str]:
    def proc(value: str) -> str:
        value = value.strip()
        if not pattern.match(value):
            raise InvalidAnswer(message)
        return value
    return proc


def _nonempty(what: str) -> Callable[[str], str]:
    def proc(value: str) -> str:
        if not value.strip():
            raise InvalidAnswer(f"{what} cannot be empty")
        return value.strip()
    return proc


def _text(value: str) -> str:
    return value


def _count(value: str) -> int:
    if not value.strip():
        raise InvalidAnswer("give a number of entries, 0 or more")
    try:
        n = int(value.strip())
    except ValueError:
        raise InvalidAnswer(f"{value!r} is not a valid integer") from None
    if not 0 <= n <= MAX_ITEMS:
        raise InvalidAnswer(f"{n} is not in the range 0<=x<={MAX_ITEMS}")
    return n


def _csv(value: str) -> list[str]:
    return [v.strip() for v in value.split(",") if v.strip()]


def collect(registry: Registry, ui: Prompter) -> tuple[Answers, Package, ArchitectureFile]:
    """Ask everything an application package needs, through `ui`; checking and writing are
    the generator's (shared with `--answers`)."""
    ui.step("1/5 General data")
    package = ui.ask("Package name (lower case, e.g. my_mission)",
                     _check(PACKAGE_NAME, "use lower-case letters, digits and '_', "
                                          "starting with a letter"))
    name = ui.ask("Application name", _nonempty("the name"))
    version = ui.ask("Version", _check(VERSION, "expected MAJOR.MINOR.PATCH, e.g. 1.0.0"),
                     default="1.0.0")
    description = ui.ask("Description", _text, default=name)
    maintainer = ui.ask("Maintainer", _nonempty("the maintainer"))
    email = ui.ask("Maintainer e-mail", _check(EMAIL, "not a valid e-mail address"))
    license_ = ui.ask("Licence", _text, default="Apache-2.0")
    missions = registered_missions()

    def mission_of(v: str) -> str:
        try:
            return check_mission(v.strip())
        except ConfigError as exc:
            raise InvalidAnswer(str(exc)) from None
    # the mission `mrta demo` runs it as: its simulation launch file is derived from that
    # mission's (missionfiles.py), so a new application runs there as made (issue 51)
    mission = ui.ask(f"Mission it runs in `mrta demo` ({', '.join(missions) or 'none installed'}"
                     "; empty for none)", mission_of, default="", show_default=False)
    depends = _csv(ui.ask("Other dependencies (comma-separated)", _text, default="",
                                    show_default=False))

    ui.step("2/5 Architecture")
    archs = registry.architectures()
    filters = {}
    for axis, options in (("robots", "ST/MT"), ("tasks", "SR/MR"), ("allocations", "IA/TA")):
        def proc(v: str, axis=axis) -> str | None:
            if not v.strip():
                return None
            try:
                return taxonomy_value(axis, v)
            except ConfigError:  # its text names `arch list`'s flag, no prompt's (issue 51)
                raise InvalidAnswer(f"{v.strip()!r} is no {axis} type: give {options}, or "
                                    "nothing for any (an architecture is chosen by name next)"
                                    ) from None
        filters[axis] = ui.ask(f"Filter by {axis} type ({options}, empty for any)", proc,
                               default="", show_default=False)
    shown = [(p, a) for p, a in archs if matches_taxonomy(a, **filters)]
    if not shown:
        raise ConfigError("no registered architecture matches these filters "
                          f"(registered: {', '.join(p.name for p, _ in archs) or 'none'})")
    for i, (p, a) in enumerate(shown, 1):
        ui.say(f"  {i}. {p.name}: {a.name} [{a.taxonomy}]")

    def pick(v: str) -> tuple[Package, ArchitectureFile]:
        v = v.strip()
        if v.isdigit() and 1 <= int(v) <= len(shown):
            chosen = shown[int(v) - 1]
        else:
            chosen = next(((p, a) for p, a in shown if v in (p.name, a.name)), None)
            if chosen is None:
                raise InvalidAnswer(f"choose 1-{len(shown)} or a name")
        try:  # the mission of step 1 may need another (patrol: none of routes)
            check_pairing(mission, chosen[0].name)
        except ConfigError as exc:
            raise InvalidAnswer(str(exc)) from None
        return chosen
    arch_pkg, arch = ui.ask("Architecture", pick, default="1")

    ui.step("3/5 Robots and tasks")

    def ids(v: str) -> list[str]:
        out = _csv(v)
        if not out or not all(is_id(x) for x in out):
            raise InvalidAnswer("give one or more ids (letters, digits, '_', '-', '.'), "
                                "comma-separated")
        if len(set(out)) != len(out):
            raise InvalidAnswer("ids must be unique")
        return out
    robot_ids = ui.ask("Robot ids (comma-separated)", ids)
    task_ids = ui.ask("Task ids of the application (comma-separated)", ids)
    robots: dict[str, list[str]] = {}
    for rid in robot_ids:
        def subset(v: str) -> list[str]:
            chosen = ids(v)
            bad = [t for t in chosen if t not in task_ids]
            if bad:
                raise InvalidAnswer(f"unknown task {bad[0]!r}; tasks are {', '.join(task_ids)}")
            return chosen
        robots[rid] = ui.ask(f"Tasks {rid} can do", subset, default=",".join(task_ids))

    ui.step("4/5 Parameters")
    answers = Answers(package=package, name=name, architecture=arch_pkg.name, robots=robots,
                      configs={}, version=version, description=description,
                      maintainer=maintainer, email=email, license=license_, depends=depends,
                      mission=mission)
    layers_id = layers_config_id(_application(arch_pkg, answers))
    for c in list(arch.configs):
        if c.id == layers_id:  # asked after the robots' and tasks' files: their plugins tell
            _until_accepted(ui, arch_pkg, arch, answers)
            arch = restrict_layers(arch_pkg, arch, answers)
        _ask_config(ui, answers, arch, c.id, {})
    return answers, arch_pkg, arch


def _until_accepted(ui: Prompter, arch_pkg: Package, arch: ArchitectureFile,
                    answers: Answers) -> None:
    """The robots' and tasks' files, checked by the architecture, asked for again until it
    accepts them: which layer sections to ask for is known only from files it accepts."""
    while True:
        _, files = without_layers(arch_pkg, arch, answers)
        try:
            check_package_files(files, _application(arch_pkg, answers))
            return
        except PackageRefused as exc:
            ui.say(f"Error: {exc}")
            ask_again(ui, answers, arch, exc.generated)


def _application(arch_pkg: Package, answers: Answers) -> ApplicationFile:
    return ApplicationFile(arch_pkg.name, answers.name,
                           [RobotEntry(r, t) for r, t in answers.robots.items()])


def _ask_config(ui: Prompter, answers: Answers, arch: ArchitectureFile, config_id: str,
                previous: dict, robot: str | None = None) -> None:
    """The answers for one config template into `answers.configs` — every robot's, or only
    `robot`'s, for the per-robot one — offering `previous` answers as defaults."""
    c = arch.config(config_id)
    if c.id == arch.config_id:
        per_robot = answers.configs.setdefault(c.id, {})
        for rid, tasks in answers.robots.items():
            if robot in (None, rid):
                ui.section(f"{rid}_{c.id}")
                per_robot[rid] = _ask_children(ui, c.children, rid, tasks, previous.get(rid))
    elif c.children:
        ui.section(c.id)
        known = list(dict.fromkeys(t for ts in answers.robots.values() for t in ts))
        answers.configs[c.id] = _ask_children(ui, c.children, c.id, None, previous,
                                              task_ids=known)


def ask_again(ui: Prompter, answers: Answers, arch: ArchitectureFile, generated: str) -> None:
    """The answers behind the generated file `generated` (config/robot1_alliance_params.yaml),
    asked for once more with the earlier ones as defaults: the architecture refused the file."""
    stem = generated.rsplit("/", 1)[-1].removesuffix(".yaml")
    for rid in answers.robots:
        if stem == f"{rid}_{arch.config_id}":
            _ask_config(ui, answers, arch, arch.config_id, answers.configs[arch.config_id],
                        robot=rid)
            return
    if arch.config(stem) is None:
        raise ConfigError(f"{generated}: not a file of the parameters asked for")
    _ask_config(ui, answers, arch, stem, answers.configs.get(stem) or {})


def _ask_children(ui: Prompter, children: list[Node], path: str,
                  tasks: list[str] | None, previous: Any = None,
                  task_ids: list[str] | None = None, this_id: str | None = None) -> dict:
    """The answers for `children`. `task_ids` (a file of the application's tasks): an array
    whose entries have an `id` holds one entry per task given in step 3, its `id` filled in —
    not asked twice (issue 51, the newcomer's list); `this_id`: that entry's id."""
    before = previous if isinstance(previous, dict) else {}
    out: dict[str, Any] = {}
    for child in children:
        if isinstance(child, Param):
            if child.value == ARRAY_SIZE or child.value == TASK_PLACEHOLDER:
                continue  # sized from the array below / filled from the robot's tasks
            if child.value and "@" not in child.value:
                continue  # fixed by the architecture
            if this_id is not None and child.name == "id":
                out["id"] = this_id  # the task's id, given in step 3
                continue
            out[child.name] = _ask_param(ui, child, f"{path}/{child.name}",
                                         before.get(child.name))
        elif isinstance(child, Params):
            out[child.name] = _ask_children(ui, child.children, f"{path}/{child.name}", tasks,
                                            before.get(child.name), task_ids=task_ids)
        else:
            key = child.name.replace("@index@", "")
            earlier = before.get(key) if isinstance(before.get(key), list) else []
            by_id = bool(task_ids) and tasks is None and any(
                isinstance(c, Param) and c.name == "id" and not c.value for c in child.children)
            if tasks is not None and _has_task_id(child):
                count = len(tasks)
                labels = tasks
            elif by_id:
                count, labels = len(task_ids), task_ids
            else:
                count = ui.ask(f"{path}: how many {key} entries", _count,
                               default=str(len(earlier)) if earlier else None)
                labels = [str(i) for i in range(count)]
            items = []
            for i in range(count):
                ui.say(f"  {child.name.replace('@index@', str(i))} ({labels[i]})")
                items.append(_ask_children(ui, child.children, f"{path}/{key}{i}", tasks,
                                           earlier[i] if i < len(earlier) else None,
                                           this_id=labels[i] if by_id else None))
            out[key] = items
    return out


def _has_task_id(node: Node) -> bool:
    if isinstance(node, Param):
        return node.value == TASK_PLACEHOLDER
    return any(_has_task_id(c) for c in node.children)


def _ask_param(ui: Prompter, p: Param, path: str, previous: Any = None) -> Any:
    """One parameter; an earlier answer (`previous`) or the template's default is offered."""
    default = p.default or None
    if previous is not None:
        default = ("true" if previous else "false") if isinstance(previous, bool) \
            else str(previous)

    def proc(v: str) -> Any:
        if v == "" and not default:
            raise InvalidAnswer(f"{p.name} is mandatory: give a value")
        try:
            return convert(p.type, v if v != "" else default, path)
        except ConfigError as exc:
            raise InvalidAnswer(str(exc)) from None
    help_ = f" — {p.tool_tip}" if p.tool_tip else ""
    return ui.ask(f"{path} [{p.type or 'string'}]{help_}", proc, default=default)


def summary(answers: Answers, arch: ArchitectureFile, files: dict[str, bytes], dest) -> str:
    lines = [f"Application {answers.name!r} ({arch.name}, {arch.taxonomy}) → {dest}",
             "Robots: " + "; ".join(f"{r}: {', '.join(t)}" for r, t in answers.robots.items()),
             "Files:"]
    lines += [f"  {rel} ({len(data)} bytes)" for rel, data in sorted(files.items())]
    return "\n".join(lines)



class Transcript:
    """A Prompter that remembers every accepted answer as typed (`said`), and answers itself
    from an earlier session's (`given`, question → answers in order) while they are still
    accepted: Ctrl-C lost every answer (issue 51, the newcomer's list) — the CLI writes `said`
    out on Ctrl-C and `mrta app new --resume FILE` hands it back, so only the rest is asked."""

    def __init__(self, inner: Prompter, given: dict[str, list[str]] | None = None):
        self.inner, self.given = inner, {q: list(a) for q, a in (given or {}).items()}
        self.said: list[tuple[str, str]] = []

    def step(self, title: str) -> None:
        self.inner.step(title)

    def section(self, title: str) -> None:
        self.inner.section(title)

    def say(self, text: str) -> None:
        self.inner.say(text)

    def ask(self, question: str, check: Callable[[str], T], default: str | None = None,
            show_default: bool = True) -> T:
        earlier = self.given.get(question)
        if earlier:
            text = earlier.pop(0)
            try:
                value = check(text)
            except InvalidAnswer:  # the session has changed since: ask
                pass
            else:
                self.inner.say(f"{question}: {text}")
                self.said.append((question, text))
                return value
        typed: list[str] = []

        def keep(text: str) -> T:
            value = check(text)
            typed.append(text)
            return value
        value = self.inner.ask(question, keep, default, show_default)
        self.said.append((question, typed[-1]))
        return value


def transcript_yaml(said: list[tuple[str, str]]) -> str:
    """The answers given, in order, as `mrta app new --resume` reads them."""
    import yaml
    head = ("# mrta app new: the answers given so far; `mrta app new --resume THIS_FILE` asks "
            "only the rest\n")
    return head + yaml.safe_dump([{"question": q, "answer": a} for q, a in said],
                                 allow_unicode=True, sort_keys=False, width=1000)


def load_transcript(path) -> dict[str, list[str]]:
    """A transcript_yaml file: question → its answers in order; ConfigError naming the line
    of an entry that is not a question and its answer."""
    from ..yamlfile import load_yaml
    doc = load_yaml(path)
    if not isinstance(doc.data, list):
        raise doc.error((), "a list of {question, answer} entries (mrta app new writes it on "
                            "Ctrl-C)")
    out: dict[str, list[str]] = {}
    for i, entry in enumerate(doc.data):
        if not (isinstance(entry, dict) and set(entry) == {"question", "answer"}
                and all(isinstance(v, str) for v in entry.values())):
            raise doc.error((i,), "each entry is a question and its answer, both text")
        out.setdefault(entry["question"], []).append(entry["answer"])
    return out
