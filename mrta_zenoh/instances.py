"""Problem instances as run input: what `mrta instance generate | show | validate` do.

An *instance* is a file an application's mission runs (`mrta demo --instance FILE`): for a
point-task application, its robots, tasks and world. The core knows no application: an
application registers its **generators** under the `mrta.instances` entry-point group, each an
`InstanceGenerator` naming the `InstanceKind` (the application's document: how to read, check and
summarise one) it writes. A pip-installed package adds its own the same way.

Generators draw from their own seed stream — a function of the generator's name and the seed
given to it, never of a run's seed — so one instance runs under many run seeds and fault draws,
and the same generator, parameters and seed give the same file byte for byte.

A generator's parameters are a msgspec Struct (`Params`); the verb turns its fields into
command-line options, so a generator needs no command-line code of its own.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, ClassVar

import msgspec

from .errors import ConfigError
from .files import write_text
from .codec import validation_fault
from .installed import entry_points
from .planning.reference import SOLUTIONS
from .sha import sha256
from .shared_reads import once
from .yamlfile import YamlDoc, did_you_mean, load_yaml, parse_yaml

GROUP = "mrta.instances"


class InstanceKind:
    """An application's instance documents. Hooks (no-op defaults where one makes sense)."""

    application: ClassVar[str] = ""

    def load(self, doc: YamlDoc) -> Any:
        """The checked document from its parsed file (ConfigError naming file, line and key):
        the file is read once, by `load`, for its kind and its document alike."""
        raise NotImplementedError

    def name(self, doc: Any) -> str:
        """What results carry for this instance (never a path)."""
        return ""

    def robots(self, doc: Any) -> list[str]:
        """The robot ids a run of this instance starts, in the document's order (an
        experiment's `n_robots`, and whom its faults may name)."""
        raise NotImplementedError

    def tasks(self, doc: Any) -> list[str]:
        """The task ids, in the document's order (an experiment's `n_tasks`)."""
        raise NotImplementedError

    def describe(self, doc: Any, *, exact_limit: int, time_limit: float,
                 solutions: int) -> dict[str, Any]:
        """What `mrta instance show` prints (JSON values): sizes, costs, reference values."""
        return {}

    def task_positions(self, doc: Any) -> dict[str, tuple[float, float]]:
        """Where each task is done, for what prices or draws a task by where it is (MURDOCH's
        bids when its tasks file gives no `locations`, the simulator's markers): {} by
        default — an application whose tasks are no points."""
        return {}

    def digest(self, doc: Any) -> str:
        """What says which instance this is, on the wire (messages naming robots and tasks by
        their index in it carry it: messages.IndexedMessage): 16 hex digits of the SHA-256 of
        the document as JSON, in its own order (the order indices count in). Override to leave
        out what does not change the indices' meaning."""
        return sha256(msgspec.json.encode(doc)).hexdigest()[:DIGEST_LENGTH]

    def admit(self, doc: Any, task_id: str, fields: dict[str, Any]) -> None:
        """Whether a task submitted at run time (mrta_zenoh.tasks) with these fields may enter
        a run of `doc`: ConfigError saying why not (naming the field). Default: no application
        task is taken at run time."""
        raise ConfigError(f"{self.application or 'this application'} takes no tasks at run "
                          "time")

    def grow(self, doc: Any, task_id: str, fields: dict[str, Any], at: float) -> Any:
        """`doc` with a task submitted at run time (mrta_zenoh.tasks) added, arriving at `at`
        (the instant it entered the run), checked as `admit` checks it: what a robot's agent
        serves it from (robot_agent.runtime.growth). ConfigError when it may not enter.
        Default: `admit`'s refusal — an application whose tasks enter at run time overrides
        both."""
        self.admit(doc, task_id, fields)
        raise ConfigError(f"{self.application or 'this application'} admits task "
                          f"{task_id!r} but cannot add it to a running mission (InstanceKind.grow)")

    def grown_problem(self, doc: Any, before: Any) -> Any:
        """The planning problem of `doc`, grown at run time (`grow`) from the one `before`:
        the tasks and their indices before keep their place, the new ones follow. Default: the
        whole problem again (`problem`); an application may compute only what is new."""
        return self.problem(doc)

    def schedule(self, doc: Any) -> list:
        """The changes `doc` schedules at run time (mrta_zenoh.tasks.intake.Scheduled: a
        summary's `submitted`, what entered a live run and when), which a run of it replays
        through its intake; [] by default."""
        return []

    def problem(self, doc: Any) -> Any:
        """The planning problem the document poses (`mrta_zenoh.planning.Problem`: robots,
        point tasks, travel times), for a planner that runs beside the robots (central's
        dispatcher). Default: ConfigError — this application's instances pose none."""
        raise ConfigError(f"{self.application or 'this application'}'s instances pose no "
                          "planning problem (robots and point tasks) a dispatcher could solve")


class InstanceGenerator:
    """A registered generator: `name`, the `kind` of document it writes, its `Params`."""

    name: ClassVar[str] = ""
    kind: ClassVar[InstanceKind]
    Params: ClassVar[type]

    def generate(self, params: Any, seed: int) -> str:
        """The document's text, a function of `params` and `seed` alone."""
        raise NotImplementedError


def generators() -> dict[str, InstanceGenerator]:
    out = {}
    for ep in entry_points(group=GROUP):
        gen = ep.load()
        gen = gen() if isinstance(gen, type) else gen
        if not isinstance(gen, InstanceGenerator):
            raise ConfigError(f"entry point {GROUP}:{ep.name} ({ep.value}) is not an "
                              "InstanceGenerator")
        out[ep.name] = gen
    return out


def generator(name: str) -> InstanceGenerator:
    gens = generators()
    if name not in gens:
        raise ConfigError(f"no instance generator {name!r}" + did_you_mean(name, gens)
                          + f" (registered: {', '.join(sorted(gens)) or 'none'})")
    return gens[name]


def kinds() -> dict[str, InstanceKind]:
    """Instance kinds by application, from the registered generators."""
    return {g.kind.application: g.kind for g in generators().values()}


def kind_of(doc: YamlDoc, application: str | None = None) -> InstanceKind:
    """The kind a parsed file is read as: `application` when given, else the file's own
    `application:` key, else the only registered kind."""
    known = kinds()
    path = doc.path
    if application is None:
        data = doc.data.get("instance", doc.data) if isinstance(doc.data, dict) else None
        named = data.get("application") if isinstance(data, dict) else None
        if isinstance(named, str):
            application = named
        elif len(known) == 1:
            return next(iter(known.values()))
        else:
            raise ConfigError(f"{path}: say which application this instance is for "
                              f"(--application; registered: {', '.join(sorted(known))})")
    if application not in known:
        raise ConfigError(f"no application reads instances named {application!r}"
                          + did_you_mean(application, known)
                          + f" (registered: {', '.join(sorted(known)) or 'none'})")
    return known[application]


@dataclass(frozen=True)
class Loaded:
    path: Path
    kind: InstanceKind
    doc: Any
    name: str = field(default="")
    digest: str = ""  # InstanceKind.digest


DIGEST_LENGTH = 16


def load(path: Path, application: str | None = None) -> Loaded:
    """Read and check an instance file (`mrta instance validate`), reading it once (once per
    agent host for all its robots: mrta_zenoh.shared_reads)."""
    return once(path, ("instance", application), lambda: _load(path, application))


def _load(path: Path, application: str | None) -> Loaded:
    parsed = load_yaml(path)
    kind = kind_of(parsed, application)
    doc = kind.load(parsed)
    return Loaded(path, kind, doc, kind.name(doc), kind.digest(doc))


def problem(path: Path, application: str | None = None) -> Any:
    """The planning problem of an instance file (InstanceKind.problem), checked as `load`."""
    loaded = load(path, application)
    return loaded.kind.problem(loaded.doc)


def show(path: Path, application: str | None = None, *, exact_limit: int = 10,
         time_limit: float = 30.0, solutions: int | None = None) -> dict[str, Any]:
    """What `mrta instance show` prints. `solutions` defaults to the run's budget
    (planning.reference.SOLUTIONS): show's "best found" is the one a run's summary compares with."""
    solutions = SOLUTIONS if solutions is None else solutions
    loaded = load(path, application)
    return {"name": loaded.name, "application": loaded.kind.application,
            **loaded.kind.describe(loaded.doc, exact_limit=exact_limit, time_limit=time_limit,
                                   solutions=solutions)}


def generate(name: str, options: dict[str, Any], seed: int, output: Path | None) -> str:
    """Run generator `name` on `options` (its Params' fields); write the text to `output`
    (whole or not at all) when given, once it reads back as its kind's valid document;
    return it."""
    gen = generator(name)
    try:
        params = msgspec.convert(options, gen.Params)
    except msgspec.ValidationError as exc:
        fault = validation_fault(exc)
        # the options are the verb's --flags: name the flag and the value, not msgspec's `$.x`
        flag = "--" + "-".join(str(p) for p in fault.path[:1]).replace("_", "-")
        value = options.get(fault.path[0]) if fault.path else None
        what = fault.what.replace("`", "")
        raise ConfigError(f"generator {name}: {flag} {value}: {what}" if fault.path
                          else f"generator {name}: {what}") from None
    text = gen.generate(params, seed)
    try:  # a generator never writes what `validate` refuses (issue 51.5): its text, read back
        gen.kind.load(parse_yaml(text, output or f"<{name} generator output>"))
    except ConfigError as exc:
        raise ConfigError(f"generator {name} made an instance validate would refuse, so "
                          f"nothing is written: {exc}") from None
    if output is not None:
        write_text(output, text)
    return text
