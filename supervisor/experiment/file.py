"""The experiment file: a typed document (msgspec), read with the line-aware YAML loader so
every error names the file, the line and the key, with a "did you mean" for a misspelt one.

    application: delivery
    architectures: [alliance, murdoch]  # optional axis: any registered architecture's name;
                           # or `architecture: NAME`, one, not an axis
    duration: 120          # simulated seconds per run
    seeds: [1, 2, 3, 4, 5]   # or seeds: 5 (1 to 5); one value stands for a one-item list
    failures: [none, robot2@40, "stall:@first@5", "partition:robot2@40+10,loss:0.1"]
                           # each one fault spec (docs/delivery.md, "Fault grammar")
    instances:             # optional: the instances runs serve (instances.py)
      generator: delivery
      robots: [5, 10, 20]
      tasks_per_robot: [1, 2]
      count: 3
      seed: 7
    overrides:             # optional sweeps: <parameter file glob>.<key path>: [values]
      robot*.timeout_duration: [2.0, 4.0]   # (mission/overrides.py; with instances, set in each
                           # run's derived packages)
    robots: [3]            # optional, without instances: the team size the file expects
                           # (checked, not varied)

Reading is two steps: the shape (msgspec converts the YAML to `ExperimentSpec`: types, unknown
and missing keys) and the values (`check`: ranges, the fault grammar, override keys, the
instances block), both naming the line of the value at fault.

The matrix is instances × architectures × failures × overrides × seeds. A *cell* is everything
that defines a run but its instance and its seed (`Cell`: the architecture, the instance's size
— its robots and tasks — the failure and the overrides), the runs a report compares together;
its runs are every instance of its size × every seed. The cells are the product of the axes
(`Experiment.axes`: architecture, size, failure, then each override key in sorted order), and
runs are numbered cell by cell, instance by instance, seed by seed. Seeds added later (`mrta
experiment --until-ci`, api.py) continue the numbering: `runs(seeds, first)`. The
instances of a block are made once, into the output folder, before the runs
(`Experiment.with_instances`); until then the matrix is counted, not listed.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import msgspec

from mrta_zenoh.codec import validation_fault
from mrta_zenoh.errors import ConfigError
from mrta_zenoh.failure import faults_problem, parse_faults
from mrta_zenoh.limits import MAX_RUNS, RUN_DURATION, SEED
from mrta_zenoh.yamlfile import YamlDoc, did_you_mean, load_yaml, plural

from .instances import Instance, InstancesSpec, Size, as_lists, check_block
from .instances import count as instance_count
from .results import measure_problem


# an experiment's runs put their robots' agents this many per process unless the file says
# otherwise: a team up to this size in one host, a larger one spread over its hosts' cores
AGENTS_PER_PROCESS = 10


class ExperimentSpec(msgspec.Struct, forbid_unknown_fields=True, kw_only=True):
    """The experiment file as written."""

    application: str
    duration: float
    seeds: list[int] | int   # an integer N: seeds 1 to N (load_experiment makes it the list)
    failures: list[str] = msgspec.field(default_factory=lambda: ["none"])
    overrides: dict[str, list[Any]] | None = None
    architecture: str | None = None
    architectures: list[str] | None = None
    instances: InstancesSpec | None = None
    robots: list[int] | int | None = None   # the team size the file was written for (checked)
    # robots' agents per process (agent hosts): the same rows as one process per robot, for a
    # fraction of the CPU; 1 when a study is about process deaths as such
    agents_per_process: int = AGENTS_PER_PROCESS


FIELDS = tuple(f.encode_name for f in msgspec.structs.fields(ExperimentSpec))
# what a value must be, for the messages of the shape check (key → its whole value)
SHAPE = {"application": "a name", "architecture": "a name (mrta arch list)",
         "architectures": "a non-empty list of names (mrta arch list)",
         "duration": "a number (simulated seconds)",
         "seeds": "a non-empty list, or N (seeds 1 to N)",
         "failures": "a non-empty list", "robots": "a number, or a non-empty list",
         "instances": "a mapping: generator: with robots:, or files:",
         "overrides": "a mapping of PARAMETER_FILE_GLOB.KEY.PATH to lists",
         "agents_per_process": "a whole number of robots' agents per process, at least 1"}
ITEM = {"seeds": "int", "failures": "str", "robots": "int", "architectures": "str"}


@dataclass(frozen=True)
class Cell:
    """Everything that defines a run but its instance and its seed: the runs of one cell are
    compared together. `architecture` is None when the file names none (the application's
    own, or `architecture:`); `size` None without an instances block."""

    failure: str
    overrides: tuple[tuple[str, Any], ...] = ()
    architecture: str | None = None
    size: Size | None = None

    @property
    def config(self) -> str:
        head = [] if self.architecture is None else [f"arch={self.architecture}"]
        if self.size is not None:
            head += [f"robots={self.size.robots}", f"tasks={self.size.tasks}"]
        return " ".join(head + [f"fail={self.failure}"]
                        + [f"{k}={v}" for k, v in self.overrides])


@dataclass(frozen=True)
class Run:
    index: int
    seed: int
    failure: str
    overrides: tuple[tuple[str, Any], ...]
    architecture: str | None = None
    instance: Instance | None = None
    agents_per_process: int = 1  # how its robots' agents run (mrta demo --agents-per-process)

    @property
    def cell(self) -> Cell:
        return Cell(self.failure, self.overrides, self.architecture,
                    self.instance.size if self.instance is not None else None)

    @property
    def config(self) -> str:
        """Everything but the instance and the seed: runs of one configuration are compared
        together."""
        return self.cell.config


@dataclass(frozen=True)
class Experiment:
    file: Path
    spec: ExperimentSpec
    doc: YamlDoc | None = None  # for the lines of errors found after loading
    instances: tuple[Instance, ...] = ()  # made by with_instances (an instances block's)

    @property
    def architectures(self) -> list[str | None]:
        """The architecture axis: the file's list, or [None] (the application's own or the
        file's one `architecture:`, not varied)."""
        return list(self.spec.architectures) if self.spec.architectures else [None]

    def with_instances(self, instances: tuple[Instance, ...]) -> "Experiment":
        """This experiment with its instances made (instances.prepare)."""
        return replace(self, instances=instances)

    def sizes(self) -> list[Size | None]:
        """The instance sizes, in order of first appearance ([None] without instances)."""
        if self.spec.instances is None:
            return [None]
        if not self.instances:
            raise ValueError("the instances are not made yet (Experiment.with_instances)")
        return list(dict.fromkeys(i.size for i in self.instances))

    def axes(self) -> list[tuple[str, list[Any]]]:
        """The matrix's axes in the order runs are numbered: architecture, size, failure, then
        the overrides."""
        overrides = self.spec.overrides or {}
        return [("architecture", self.architectures), ("size", self.sizes()),
                ("failure", list(self.spec.failures))] + [(k, list(overrides[k]))
                                                          for k in sorted(overrides)]

    def cells(self) -> list[Cell]:
        names = [name for name, _ in self.axes()]
        cells = []
        for values in itertools.product(*(v for _, v in self.axes())):
            chosen = dict(zip(names, values))
            arch, size, failure = (chosen.pop(k) for k in ("architecture", "size", "failure"))
            cells.append(Cell(failure, tuple(chosen.items()), arch, size))
        return cells

    def instances_of(self, cell: Cell, among: tuple[Instance, ...] | None = None
                     ) -> list[Instance | None]:
        if cell.size is None:
            return [None]
        return [i for i in (self.instances if among is None else among) if i.size == cell.size]

    def runs(self, seeds: list[int] | None = None, first: int = 0,
             instances: tuple[Instance, ...] | None = None) -> list[Run]:
        """One run per cell, instance of its size and seed (the file's seeds, and every
        instance, unless given), numbered from `first`."""
        seeds = self.spec.seeds if seeds is None else seeds
        combos = [(cell, inst, seed) for cell in self.cells()
                  for inst in self.instances_of(cell, instances) for seed in seeds]
        return [Run(first + i, seed, cell.failure, cell.overrides, cell.architecture, inst,
                    self.spec.agents_per_process)
                for i, (cell, inst, seed) in enumerate(combos)]

    def instance_count(self) -> int:
        """How many instances the runs serve (1: the application's own)."""
        if self.spec.instances is None:
            return 1
        return len(self.instances) or instance_count(self.spec.instances, self.file.parent)

    def count(self) -> int:
        """How many runs `runs()` would make, without making them (or the instances)."""
        overrides = self.spec.overrides or {}
        return (len(self.architectures) * self.instance_count() * len(self.spec.failures)
                * math.prod(len(v) for v in overrides.values()) * len(self.spec.seeds))

    def check_runs(self, max_runs: int = MAX_RUNS) -> None:
        """Refuse a matrix of more than `max_runs` runs before anything starts (a list of a
        million seeds, or overrides whose product is a million)."""
        n = self.count()
        if n > max_runs:
            overrides = self.spec.overrides or {}
            combos = math.prod(len(v) for v in overrides.values())
            seeds = len(self.spec.seeds)
            parts = []
            if self.spec.instances is not None:
                parts.append(plural(self.instance_count(), "instance"))
            if self.spec.architectures:
                parts.append(plural(len(self.architectures), "architecture"))
            parts += [plural(len(self.spec.failures), "failure"),
                      f"{combos:,} override combinations",
                      f"{seeds:,} {'seed' if seeds == 1 else 'seeds'}"]
            raise ConfigError(
                f"this experiment makes {n:,} runs ({' × '.join(parts)}), more than --max-runs "
                f"{max_runs:,}: pass --max-runs {n} to start them all", file=str(self.file))

    def check_against(self, robots: list[str], processes: tuple[str, ...] = ()) -> None:
        """Every failure names one of the application's `robots` (with instances: of every
        instance) or of the architecture's own `processes` (central's dispatcher), and happens
        before the end of a run; a ConfigError naming the line otherwise (a failure of an
        unknown robot would fail every run the same way)."""
        teams = [(i.name, list(i.robots) + list(processes)) for i in self.instances] \
            or [("", robots + list(processes))]
        for i, spec in enumerate(self.spec.failures):
            if spec == "none":
                continue
            for name, team in teams:
                problem = faults_problem(parse_faults(spec), team, self.spec.duration)
                if problem:
                    where = f" (instance {name})" if name else ""
                    raise self.error(("failures", i), f"failures[{i}]: {problem}{where}")

    def check_team(self, n_robots: int, application: str) -> None:
        """`robots:` names the team size the application starts (it is not varied)."""
        if self.spec.robots is not None and self.spec.robots != [n_robots]:
            raise self.error(("robots",), f"robots: the application {application!r} has "
                                          f"{n_robots} robots (its launch file starts them); "
                                          f"got {self.spec.robots}")

    def error(self, path: tuple, message: str) -> ConfigError:
        if self.doc is not None:
            return self.doc.error(path, message)
        return ConfigError(message, file=str(self.file))


def _failure_problem(spec: str) -> str | None:
    """Why an entry of `failures` is no fault spec (None: it is one, or `none`)."""
    if spec == "none":
        return None
    try:
        parse_faults(spec)
    except ValueError as exc:
        return f"{exc}, or none"
    return None


def load_experiment(path: Path) -> Experiment:
    doc = load_yaml(path)
    spec = _lists(doc, _shape(doc))
    check(doc, spec, Path(path).parent)
    return Experiment(Path(path), spec, doc)


def _lists(doc: YamlDoc, spec: ExperimentSpec) -> ExperimentSpec:
    """The scalar forms as the lists they stand for: `seeds: N` is seeds 1 to N (N runs per
    cell, the seeds a file of `seeds: [1, …, N]` names), `robots: 5` is [5], and in an
    instances block `robots:`, `tasks:` and `tasks_per_robot:` one value each."""
    if isinstance(spec.seeds, int):
        if not 1 <= spec.seeds <= MAX_RUNS:
            raise doc.error(("seeds",), f"seeds: N means seeds 1 to N: expected 1 ≤ N ≤ "
                                        f"{MAX_RUNS:,}, got {spec.seeds}")
        spec.seeds = list(range(1, spec.seeds + 1))
    if isinstance(spec.robots, int):
        spec.robots = [spec.robots]
    if spec.instances is not None:
        spec.instances = as_lists(spec.instances)
    return spec


def _shape(doc: YamlDoc) -> ExperimentSpec:
    """The document as ExperimentSpec; a ConfigError at the key's line otherwise."""
    if not isinstance(doc.data, dict):
        raise doc.error((), "an experiment file must be a mapping")
    try:
        return msgspec.convert(doc.data, ExperimentSpec, strict=True)
    except msgspec.ValidationError as exc:
        fault = validation_fault(exc)
    path = fault.path
    if path[:1] == ("instances",) and isinstance(doc.data.get("instances"), dict):
        doc.convert(("instances",), InstancesSpec)  # its own key names the line
    if fault.unknown:
        raise doc.error(path + (fault.unknown,), f"unknown key {fault.unknown!r}"
                        + did_you_mean(fault.unknown, FIELDS))
    if fault.missing:
        raise doc.error(path, f"missing mandatory key {fault.missing!r}")
    key = path[0]
    if key == "overrides" and (len(path) == 1 or fault.in_key):
        raise doc.error(path, f"overrides must be {SHAPE[key]}")
    if key == "overrides":
        raise doc.error(path[:2], f"{path[1]}: expected a non-empty list of values")
    if len(path) == 1 or key not in ITEM:
        raise doc.error(path[:1], f"{key} must be {SHAPE[key]}")
    value = doc.data[key][path[1]]
    raise doc.error(path[:2], f"{key}[{path[1]}] must be {ITEM[key]}, got {value!r:.40}")


def check(doc: YamlDoc, spec: ExperimentSpec, base: Path) -> None:
    """The values of a well-shaped document: names, ranges, fault specs, override keys, the
    instances block (`base`: the folder its files are relative to)."""
    for key in ("application", "architecture"):
        if getattr(spec, key) == "":
            raise doc.error((key,), f"{key} must be {SHAPE[key]}")
    if spec.architecture is not None and spec.architectures is not None:
        raise doc.error(("architectures",), "give architecture: (one) or architectures: (an "
                                            "axis), not both")
    problem = RUN_DURATION.problem(spec.duration)  # 1e308 is finite, and never ends
    if problem:
        raise doc.error(("duration",), f"duration (simulated seconds) {problem}")
    if spec.agents_per_process < 1:
        raise doc.error(("agents_per_process",), f"agents_per_process must be "
                        f"{SHAPE['agents_per_process']}, got {spec.agents_per_process}")
    for key, problem_of in (("seeds", SEED.problem), ("failures", _failure_problem),
                            ("robots", None), ("architectures", _name_problem)):
        values = getattr(spec, key)
        if values is None:
            continue
        if not values:
            raise doc.error((key,), f"{key} must be {SHAPE[key]}")
        seen: set = set()  # linear: 100,000 seeds took 36 s as `v in values[:i]`
        for i, v in enumerate(values):
            problem = problem_of(v) if problem_of is not None else None
            if problem is None and v in seen:
                problem = f"{v!r} is listed twice"
            if problem:
                raise doc.error((key, i), f"{key}[{i}]: {problem}")
            seen.add(v)
    if spec.instances is not None:
        if spec.robots is not None:
            raise doc.error(("robots",), "robots: with instances, the team sizes are the "
                                         "instances block's (instances: robots: [N, …])")
        check_block(doc, spec.instances, base)
    for key, values in (spec.overrides or {}).items():
        if "." not in key:
            raise doc.error(("overrides", key), f"{key!r}: expected FILE_GLOB.KEY.PATH, e.g. "
                                                "robot*.timeout_duration")
        if measure_problem(key):
            raise doc.error(("overrides", key), measure_problem(key))
        if not values:
            raise doc.error(("overrides", key), f"{key}: expected a non-empty list of values")


def _name_problem(name: str) -> str | None:
    return "expected a name (mrta arch list)" if not name.strip() else None
