"""The experiment file: a typed document (msgspec), read with the line-aware YAML loader so
every error names the file, the line and the key, with a "did you mean" for a misspelt one.

    application: patrol
    architecture: murdoch  # optional: the application under another architecture
    duration: 120          # simulated seconds per run
    seeds: [1, 2, 3, 4, 5]
    failures: [none, robot2@40, stall:robot2@40, "partition:robot2@40+10,loss:0.1"]
                           # each one fault spec (docs/delivery.md, "Fault grammar")
    overrides:             # optional sweeps: <parameter file glob>.<key path>: [values]
      robot*.timeout_duration: [2.0, 4.0]
    robots: [3]            # optional: the team size the file expects (checked, not varied)

Reading is two steps: the shape (msgspec converts the YAML to `ExperimentSpec`: types, unknown
and missing keys) and the values (`check`: ranges, the fault grammar, override keys), both
naming the line of the value at fault.

The matrix is the product of the *axes* (`Experiment.axes`: failures, then each override key
in sorted order) × the seeds: one `Cell` per combination of axis values, one `Run` per cell and
seed, numbered in that order. A new axis — an `instances:` block or an `architectures:` list —
is a field of ExperimentSpec, an entry of `axes()` and a field of Cell; the runs, their
numbering and the report's cells follow from those. Seeds added later (`mrta experiment
--until-ci`, experiment.py) continue the numbering: `runs(seeds, first)`.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import msgspec

from mrta_zenoh.codec import validation_fault
from mrta_zenoh.errors import ConfigError
from mrta_zenoh.failure import faults_problem, parse_faults
from mrta_zenoh.limits import MAX_RUNS, RUN_DURATION, SEED
from mrta_zenoh.yamlfile import YamlDoc, did_you_mean, load_yaml, plural

from .results import measure_problem


class ExperimentSpec(msgspec.Struct, forbid_unknown_fields=True, kw_only=True):
    """The experiment file as written."""

    application: str
    duration: float
    seeds: list[int]
    failures: list[str] = msgspec.field(default_factory=lambda: ["none"])
    overrides: dict[str, list[Any]] | None = None
    architecture: str | None = None
    robots: list[int] | None = None   # the team size the file was written for (checked)


FIELDS = tuple(f.encode_name for f in msgspec.structs.fields(ExperimentSpec))
# what a value must be, for the messages of the shape check (key → its whole value)
SHAPE = {"application": "a name", "architecture": "a name (mrta arch list)",
         "duration": "a number (simulated seconds)", "seeds": "a non-empty list",
         "failures": "a non-empty list", "robots": "a non-empty list",
         "overrides": "a mapping of PARAMETER_FILE_GLOB.KEY.PATH to lists"}
ITEM = {"seeds": "int", "failures": "str", "robots": "int"}


@dataclass(frozen=True)
class Cell:
    """Everything that defines a run but its seed: runs of one cell are compared together."""

    failure: str
    overrides: tuple[tuple[str, Any], ...] = ()

    @property
    def config(self) -> str:
        return " ".join([f"fail={self.failure}"] + [f"{k}={v}" for k, v in self.overrides])


@dataclass(frozen=True)
class Run:
    index: int
    seed: int
    failure: str
    overrides: tuple[tuple[str, Any], ...]

    @property
    def cell(self) -> Cell:
        return Cell(self.failure, self.overrides)

    @property
    def config(self) -> str:
        """Everything but the seed: runs of one configuration are compared together."""
        return self.cell.config


@dataclass(frozen=True)
class Experiment:
    file: Path
    spec: ExperimentSpec
    doc: YamlDoc | None = None  # for the lines of errors found after loading

    def axes(self) -> list[tuple[str, list[Any]]]:
        """The matrix's axes in the order runs are numbered: failures, then the overrides."""
        overrides = self.spec.overrides or {}
        return [("failure", list(self.spec.failures))] + [(k, list(overrides[k]))
                                                          for k in sorted(overrides)]

    def cells(self) -> list[Cell]:
        names = [name for name, _ in self.axes()]
        cells = []
        for values in itertools.product(*(v for _, v in self.axes())):
            chosen = dict(zip(names, values))
            failure = chosen.pop("failure")
            cells.append(Cell(failure, tuple(chosen.items())))
        return cells

    def runs(self, seeds: list[int] | None = None, first: int = 0) -> list[Run]:
        """One run per cell and seed (the file's seeds unless given), numbered from `first`."""
        seeds = self.spec.seeds if seeds is None else seeds
        return [Run(first + i, seed, cell.failure, cell.overrides)
                for i, (cell, seed) in enumerate(itertools.product(self.cells(), seeds))]

    def count(self) -> int:
        """How many runs `runs()` would make, without making them."""
        return math.prod(len(v) for _, v in self.axes()) * len(self.spec.seeds)

    def check_runs(self, max_runs: int = MAX_RUNS) -> None:
        """Refuse a matrix of more than `max_runs` runs before anything starts (a list of a
        million seeds, or overrides whose product is a million)."""
        n = self.count()
        if n > max_runs:
            combos = math.prod(len(v) for _, v in self.axes()[1:])
            seeds = len(self.spec.seeds)
            raise ConfigError(
                f"this experiment makes {n:,} runs ({plural(len(self.spec.failures), 'failure')}"
                f" × {combos:,} override combinations × {seeds:,} "
                f"{'seed' if seeds == 1 else 'seeds'}), more than --max-runs "
                f"{max_runs:,}: pass --max-runs {n} to start them all", file=str(self.file))

    def check_against(self, robots: list[str]) -> None:
        """Every failure names one of the application's `robots` and happens before the end
        of a run; a ConfigError naming the line otherwise (a failure of an unknown robot would
        fail every run the same way)."""
        for i, spec in enumerate(self.spec.failures):
            if spec == "none":
                continue
            problem = faults_problem(parse_faults(spec), robots, self.spec.duration)
            if problem:
                raise self.error(("failures", i), f"failures[{i}]: {problem}")

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
    spec = _shape(doc)
    check(doc, spec)
    return Experiment(Path(path), spec, doc)


def _shape(doc: YamlDoc) -> ExperimentSpec:
    """The document as ExperimentSpec; a ConfigError at the key's line otherwise."""
    if not isinstance(doc.data, dict):
        raise doc.error((), "an experiment file must be a mapping")
    try:
        return msgspec.convert(doc.data, ExperimentSpec, strict=True)
    except msgspec.ValidationError as exc:
        fault = validation_fault(exc)
    path = fault.path
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


def check(doc: YamlDoc, spec: ExperimentSpec) -> None:
    """The values of a well-shaped document: names, ranges, fault specs, override keys."""
    for key in ("application", "architecture"):
        if getattr(spec, key) == "":
            raise doc.error((key,), f"{key} must be {SHAPE[key]}")
    problem = RUN_DURATION.problem(spec.duration)  # 1e308 is finite, and never ends
    if problem:
        raise doc.error(("duration",), f"duration (simulated seconds) {problem}")
    for key, problem_of in (("seeds", SEED.problem), ("failures", _failure_problem),
                            ("robots", None)):
        values = getattr(spec, key)
        if values is None:
            continue
        if not values:
            raise doc.error((key,), f"{key} must be {SHAPE[key]}")
        for i, v in enumerate(values):
            problem = problem_of(v) if problem_of is not None else None
            if problem:
                raise doc.error((key, i), f"{key}[{i}]: {problem}")
    for key, values in (spec.overrides or {}).items():
        if "." not in key:
            raise doc.error(("overrides", key), f"{key!r}: expected FILE_GLOB.KEY.PATH, e.g. "
                                                "robot*.timeout_duration")
        if measure_problem(key):
            raise doc.error(("overrides", key), measure_problem(key))
        if not values:
            raise doc.error(("overrides", key), f"{key}: expected a non-empty list of values")
