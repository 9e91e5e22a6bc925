"""An experiment's `instances:` block: which instances its runs serve, made once into the output
folder before any run starts (docs/statistics.md, "Instances"; the README's experiment section).

    instances:                 # generated: every size, `count` instances each
      generator: delivery      # a generator registered under mrta.instances
      parameters: {walls: 1}   # its other parameters (mrta instance generate GENERATOR --help)
      robots: [5, 10, 20]      # or one size: robots: 5 (so tasks:, tasks_per_robot:)
      tasks: [5, 10]           # crossed with robots (every pair); or tasks_per_robot: [1, 2];
                               # neither: as many tasks as robots
      count: 3                 # instances per size
      seed: 7                  # instance i of a size is the generator's with seed 7 + i

    instances:                 # or files, relative to the experiment file
      files: ["instances/*.yaml"]

Instance i of a size is exactly what `mrta instance generate GENERATOR --robots N --tasks M
--seed SEED+i [PARAMETERS]` writes, so a researcher can make any of them by hand; the seed of an
instance is its generator's own stream, never a run's. Each instance is written (or, for
`files:`, copied) once to OUTPUT/instances/<name>.yaml, and every run of it gets that file as
`mrta demo --instance` — a run can be repeated by hand from its folder and that file. The name
is the instance's own (the generator's `delivery-r5-t10-8`: generator, sizes and seed; a file's
`name:` or stem), never a path: results.csv's `instance` column, unique in an experiment.
"""

from __future__ import annotations

import glob
import math
import re
import tempfile
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import msgspec

from mrta_zenoh import instances as registry
from mrta_zenoh.codec import validation_fault
from mrta_zenoh.errors import ConfigError
from mrta_zenoh.files import write_atomically, write_text
from mrta_zenoh.keys import ID_PATTERN
from mrta_zenoh.limits import SEED
from mrta_zenoh.yamlfile import YamlDoc, did_you_mean

FOLDER = "instances"     # OUTPUT/instances/<name>.yaml
MAX_COUNT = 1000         # instances per size: a typo must not generate a million files
SIZES = ("robots", "tasks")  # the generator parameters the block's lists set
_NAME = re.compile(rf"^{ID_PATTERN}$")


class InstancesSpec(msgspec.Struct, forbid_unknown_fields=True, kw_only=True):
    """The `instances:` block as written: a generator and its sizes, or files."""

    generator: str | None = None
    parameters: dict[str, Any] = {}
    robots: list[int] | int | None = None      # a number: one size (as_lists)
    tasks: list[int] | int | None = None
    tasks_per_robot: list[float] | float | None = None
    count: int = 1
    seed: int = 0
    files: list[str] | None = None


def as_lists(spec: InstancesSpec) -> InstancesSpec:
    """The block with `robots: 5`, `tasks: 10`, `tasks_per_robot: 2` as the one-value lists
    they stand for."""
    for key in SIZES + ("tasks_per_robot",):
        value = getattr(spec, key)
        if value is not None and not isinstance(value, list):
            setattr(spec, key, [value])
    return spec


GENERATED_ONLY = ("parameters", "robots", "tasks", "tasks_per_robot", "count", "seed")


@dataclass(frozen=True)
class Size:
    """One size of a generated block: `count` instances of `robots` robots and `tasks` tasks."""

    robots: int
    tasks: int


@dataclass(frozen=True)
class Instance:
    """One instance the runs serve: its name, sizes and robots (for the fault checks), and the
    file every run of it gets (`--instance`)."""

    name: str
    n_robots: int
    n_tasks: int
    robots: tuple[str, ...]
    path: Path

    @property
    def size(self) -> Size:
        return Size(self.n_robots, self.n_tasks)


def tasks_for(robots: int, per_robot: float) -> int:
    """`tasks_per_robot` × robots, to the nearest whole task (halves up): 1.5 per robot of 5
    robots is 8 tasks."""
    return math.floor(robots * per_robot + 0.5)


def sizes(spec: InstancesSpec) -> list[Size]:
    """Every (robots, tasks) pair of a generated block, robots outer, in the order written."""
    out = []
    for r in spec.robots or []:
        if spec.tasks is not None:
            tasks = spec.tasks
        elif spec.tasks_per_robot is not None:
            tasks = [tasks_for(r, k) for k in spec.tasks_per_robot]
        else:
            tasks = [r]
        for m in tasks:
            if Size(r, m) not in out:
                out.append(Size(r, m))
    return out


def file_paths(spec: InstancesSpec, base: Path) -> list[Path]:
    """The files `files:` names, each glob relative to `base` (the experiment file's folder),
    sorted within a glob, each file once."""
    out: list[Path] = []
    for pattern in spec.files or []:
        full = pattern if Path(pattern).is_absolute() else str(base / pattern)
        for p in sorted(glob.glob(full)):
            if Path(p).is_file() and Path(p) not in out:
                out.append(Path(p))
    return out


def count(spec: InstancesSpec, base: Path) -> int:
    """How many instances the block makes, without making them."""
    if spec.files is not None:
        return len(file_paths(spec, base))
    return len(sizes(spec)) * spec.count


# ------------------------------------------------------------------ checks at load
def check_block(doc: YamlDoc, spec: InstancesSpec, base: Path) -> None:
    """The values of a well-shaped block, each refused at its line: one source (generator or
    files), sizes that make sense, a generator that is registered, its parameters."""
    at = ("instances",)
    if (spec.generator is None) == (spec.files is None):
        raise doc.error(at, "instances: give either generator: (with robots:) or files:, "
                            "not both" if spec.files is not None else
                            "instances: give generator: (with robots:) or files: [GLOB]")
    if spec.files is not None:
        extra = [k for k in GENERATED_ONLY if k in (doc.data.get("instances") or {})]
        if extra:
            raise doc.error(at + (extra[0],), f"instances: {extra[0]} is for a generator; "
                                              "files: are used as they are")
        if not spec.files or any(not f.strip() for f in spec.files):
            raise doc.error(at + ("files",), "files: expected a non-empty list of file "
                                             "globs, e.g. [\"instances/*.yaml\"]")
        for i, pattern in enumerate(spec.files):
            if not file_paths(InstancesSpec(files=[pattern]), base):
                raise doc.error(at + ("files", i), f"files[{i}]: {pattern!r} matches no file "
                                                   f"(relative to {base})")
        return
    if not spec.generator:
        raise doc.error(at + ("generator",), "generator must be a name (mrta instance "
                                             "generate --help lists them)")
    if spec.robots is None:
        raise doc.error(at, "instances: a generator needs robots: [N, …], the team sizes")
    if spec.tasks is not None and spec.tasks_per_robot is not None:
        raise doc.error(at + ("tasks_per_robot",), "give tasks: or tasks_per_robot:, not both")
    for key, low in (("robots", 1), ("tasks", 0), ("tasks_per_robot", 0)):
        values = getattr(spec, key)
        if values is None:
            continue
        if not values:
            raise doc.error(at + (key,), f"{key}: expected a non-empty list")
        for i, v in enumerate(values):
            if not (math.isfinite(v) and v >= low) or (key == "tasks_per_robot" and v <= 0):
                raise doc.error(at + (key, i), f"{key}[{i}]: expected a number "
                                               f"{'> 0' if key != 'tasks' else '≥ 0'}, got {v!r}")
    if not 1 <= spec.count <= MAX_COUNT:
        raise doc.error(at + ("count",), f"count: instances per size, 1 to {MAX_COUNT}, "
                                         f"got {spec.count}")
    problem = SEED.problem(spec.seed) or SEED.problem(spec.seed + spec.count - 1)
    if problem:
        raise doc.error(at + ("seed",), f"seed: {problem}")
    for key in SIZES:
        if key in spec.parameters:
            raise doc.error(at + ("parameters", key), f"parameters: {key} is the block's own "
                                                      f"list ({key}: [N, …]), not a parameter")
    gens = registry.generators()
    if spec.generator not in gens:
        raise doc.error(at + ("generator",), f"no instance generator {spec.generator!r}"
                        + did_you_mean(spec.generator, gens)
                        + f" (registered: {', '.join(sorted(gens)) or 'none'})")
    gen = gens[spec.generator]
    fields = [f.encode_name for f in msgspec.structs.fields(gen.Params)]
    for key in SIZES:
        if key not in fields:
            raise doc.error(at + ("generator",), f"generator {spec.generator!r} has no "
                                                 f"{key!r} parameter: it cannot make sizes")
    generator_params(doc, spec, gen, Size(spec.robots[0], sizes(spec)[0].tasks))


def generator_params(doc: YamlDoc | None, spec: InstancesSpec, gen, size: Size) -> Any:
    """The generator's Params for one size: the block's `parameters` and the size, checked by
    the generator's own type (an unknown key or a bad value named at its line)."""
    data = {**spec.parameters, "robots": size.robots, "tasks": size.tasks}
    try:
        return msgspec.convert(data, gen.Params)
    except msgspec.ValidationError as exc:
        fault = validation_fault(exc)
    fields = [f.encode_name for f in msgspec.structs.fields(gen.Params)]
    key = fault.unknown or (fault.path[0] if fault.path else "")
    where = ("instances",) + (("parameters", key) if key not in SIZES else (key,))
    what = (f"unknown parameter {key!r} of generator {spec.generator!r}"
            + did_you_mean(key, fields) if fault.unknown
            else f"{key}: {fault.what.replace('`', '')}")
    if doc is None:
        raise ConfigError(what)
    raise doc.error(where, what)


# ------------------------------------------------------------------ made once, before the runs
def prepare(spec: InstancesSpec, application: str, base: Path, output: Path,
            doc: YamlDoc | None = None, seeds: range | None = None) -> tuple[Instance, ...]:
    """Every instance of the block, written to OUTPUT/instances/ (the same block gives the same
    files, byte for byte) and read back as the application reads it: a file the application
    cannot run is refused here, naming it, before any run starts. `seeds`: the generator seeds
    of each size (default: the block's own, `seed` to `seed + count - 1`; --until-ci's blocks
    of instances take the next ones: experiment.py)."""
    folder = output / FOLDER
    folder.mkdir(parents=True, exist_ok=True)
    made: list[Instance] = []
    if spec.files is not None:
        for path in file_paths(spec, base):
            loaded = registry.load(path, application)
            made.append(_written(loaded, path.suffix or ".yaml", folder,
                                 path.read_bytes().decode("utf-8")))
        return _distinct(made, doc)
    gen = registry.generator(spec.generator)
    if gen.kind.application != application:
        raise _error(doc, ("instances", "generator"),
                     f"generator {spec.generator!r} writes {gen.kind.application!r} "
                     f"instances, not {application!r} ones")
    for size in sizes(spec):
        params = generator_params(doc, spec, gen, size)
        for seed in seeds if seeds is not None else range(spec.seed, spec.seed + spec.count):
            try:
                text = gen.generate(params, seed)
            except ConfigError as exc:
                raise _error(doc, ("instances",), f"instances of {size.robots} robots and "
                             f"{size.tasks} tasks (seed {seed}): {exc.detail}") from None
            # read back as the application reads a file; a document without a name of its own
            # is named by its stem, the generator, sizes and seed
            with tempfile.TemporaryDirectory(prefix=".staging-", dir=folder) as tmp:
                staged = Path(tmp) / f"{spec.generator}-r{size.robots}-t{size.tasks}-{seed}.yaml"
                staged.write_text(text, encoding="utf-8")
                loaded = registry.load(staged, application)
            made.append(_written(loaded, ".yaml", folder, text))
    return _distinct(made, doc)


def place(instances: tuple[Instance, ...], output: Path) -> tuple[Instance, ...]:
    """The instances, made elsewhere (a staging folder: experiment.prepare_experiment makes
    them before it knows the output folder may be written), copied to OUTPUT/instances/ and
    pointing there."""
    folder = output / FOLDER
    folder.mkdir(parents=True, exist_ok=True)
    placed = []
    for inst in instances:
        path = folder / inst.path.name
        data = inst.path.read_bytes()  # byte for byte: the digest of the matrix reads them
        write_atomically(path, lambda tmp: tmp.write_bytes(data))
        placed.append(replace(inst, path=path.resolve()))
    return tuple(placed)


def _distinct(made: list[Instance], doc: YamlDoc | None) -> tuple[Instance, ...]:
    names: dict[str, Instance] = {}
    for inst in made:
        if inst.name in names:
            raise _error(doc, ("instances",), f"two instances are named {inst.name!r}: "
                         "results.csv tells instances apart by name (give the files distinct "
                         "names)")
        names[inst.name] = inst
    return tuple(made)


def _written(loaded: registry.Loaded, suffix: str, folder: Path, text: str) -> Instance:
    """The instance's file in the output folder, named by the instance."""
    if not _NAME.match(loaded.name):
        raise ConfigError(f"instance name {loaded.name!r}: expected 1 to 64 of A-Z a-z 0-9 _ . -, "
                          "not starting with . or - (it names a file and a results.csv cell)",
                          file=str(loaded.path))
    path = folder / f"{loaded.name}{suffix}"
    write_text(path, text)
    robots = tuple(loaded.kind.robots(loaded.doc))
    return Instance(loaded.name, len(robots), len(loaded.kind.tasks(loaded.doc)), robots,
                    path.resolve())


def _error(doc: YamlDoc | None, path: tuple, message: str) -> ConfigError:
    return doc.error(path, message) if doc is not None else ConfigError(message)
