"""Packages, architectures and applications: what rospack's plugin export did for rqt_mrta.

A package is a folder with a `package.xml` whose `<export>` holds
`<rqt_mrta architecture="${prefix}/rqt_mrta.xml"/>` (or `application=…`). Packages are found, in
this order (the first package of a name wins, later ones are reported as shadowed):

1. `MRTA_PACKAGE_PATH`: colon-separated folders, each a package or a tree of packages;
2. entry points in the `mrta.packages` group: the value names an importable module whose folder is
   the package, so `pip install my-arch` makes `my_arch` appear with no path set. Our own
   architecture (ALLIANCE) and application (patrol) are found this way too, from a wheel as
   from a clone: nothing is looked up relative to the source tree.

A package may also ship simulator worlds in a `worlds/` folder (`worlds/patrol.yaml` is found as
the world `patrol`).
"""

from __future__ import annotations

import importlib
import os
import re
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path


from ..errors import ConfigError
from ..installed import distribution_name, entry_points
from ..yamlfile import did_you_mean
from .model import ALLOCATION_TYPES, ROBOT_TYPES, TASK_TYPES, ApplicationFile, ArchitectureFile
from .xmlio import load_rqt_mrta, parse_xml_file

ENTRY_POINT_GROUP = "mrta.packages"
_SKIP_DIRS = {".git", "__pycache__", "node_modules", ".venv", "venv", "build", "dist"}
_MAX_DEPTH = 4


@dataclass
class Package:
    name: str
    path: Path
    version: str = ""
    description: str = ""
    maintainers: list[tuple[str, str]] = field(default_factory=list)  # (name, email)
    license: str = ""
    depends: list[str] = field(default_factory=list)
    architecture_file: Path | None = None
    application_file: Path | None = None
    origin: str = ""


def load_package_xml(path: Path, origin: str = "") -> Package:
    root = parse_xml_file(path)
    if root.tag != "package":
        raise ConfigError("the root element must be <package>", file=str(path),
                          line=root.sourceline, element=f"<{root.tag}>")

    def text(tag: str) -> str:
        el = root.find(tag)
        return (el.text or "").strip() if el is not None else ""

    name = text("name")
    if not name:
        raise ConfigError("<package> needs a <name>", file=str(path), line=root.sourceline)
    prefix = str(path.parent)
    pkg = Package(name=name, path=path.parent, version=text("version"),
                  description=" ".join(text("description").split()), license=text("license"),
                  origin=origin)
    pkg.maintainers = [((m.text or "").strip(), m.get("email", "")) for m in root.findall("maintainer")]
    pkg.depends = [(d.text or "").strip() for d in root
                   if isinstance(d.tag, str) and d.tag.endswith("depend") and d.tag != "buildtool_depend"]
    export = root.find("export")
    for el in (export if export is not None else []):
        if el.tag != "rqt_mrta":
            continue
        for attr in ("architecture", "application"):
            value = el.get(attr)
            if value is None:
                continue
            resolved = Path(value.replace("${prefix}", prefix))
            setattr(pkg, f"{attr}_file", resolved)
        unknown = set(el.attrib) - {"architecture", "application"}
        if unknown:
            bad = sorted(unknown)[0]
            raise ConfigError(f"unexpected attribute {bad!r}; expected architecture= or application="
                              + did_you_mean(bad, ["architecture", "application"]),
                              file=str(path), line=el.sourceline, element="<rqt_mrta>")
    return pkg


def _walk(root: Path, depth: int = 0):
    pkg = root / "package.xml"
    if pkg.is_file():
        yield pkg
        return  # packages do not nest (as with catkin)
    if depth >= _MAX_DEPTH:
        return
    try:
        entries = sorted(root.iterdir())
    except OSError:
        return
    for child in entries:
        if child.is_dir() and child.name not in _SKIP_DIRS and not child.name.startswith("."):
            yield from _walk(child, depth + 1)


class Registry:
    def __init__(self, search_path: list[Path] | None = None, use_entry_points: bool = True):
        self.packages: dict[str, Package] = {}
        self.problems: list[str] = []
        if search_path is None:
            env = os.environ.get("MRTA_PACKAGE_PATH", "")
            search_path = [Path(p) for p in env.split(os.pathsep) if p]
        for root in search_path:
            for xml in _walk(root):
                self._add(xml, f"MRTA_PACKAGE_PATH ({root})")
        if use_entry_points:
            for ep in entry_points(group=ENTRY_POINT_GROUP):
                try:
                    module = importlib.import_module(ep.value.split(":")[0])
                except ImportError as exc:
                    self.problems.append(f"entry point {ep.name!r} ({ep.value}): {exc}")
                    continue
                folder = Path(module.__file__).parent
                xml = folder / "package.xml"
                if xml.is_file():
                    self._add(xml, f"entry point {ep.name} ({distribution_name(ep)})")
                else:
                    self.problems.append(f"entry point {ep.name!r}: no package.xml in {folder}")

    def _add(self, xml: Path, origin: str) -> None:
        try:
            pkg = load_package_xml(xml, origin)
        except ConfigError as exc:
            self.problems.append(str(exc))
            return
        if pkg.name in self.packages:
            self.problems.append(f"package {pkg.name!r} at {pkg.path} is shadowed by "
                                 f"{self.packages[pkg.name].path}")
            return
        self.packages[pkg.name] = pkg

    def find(self, name: str) -> Package:
        pkg = self.packages.get(name)
        if pkg is None:
            raise ConfigError(f"unknown package {name!r}" + did_you_mean(name, self.packages)
                              + " (packages come from MRTA_PACKAGE_PATH and entry points)")
        return pkg

    def _models(self, attr: str, only: Callable[[Package], bool] | None = None
                ) -> list[tuple[Package, ArchitectureFile | ApplicationFile]]:
        out = []
        for pkg in self.packages.values():
            if only is not None and not only(pkg):
                continue
            f = getattr(pkg, f"{attr}_file")
            if f is None:
                continue
            if not f.is_file():
                self.problems.append(f"{pkg.path / 'package.xml'}: exported {attr} file {f} "
                                     "does not exist")
                continue
            try:
                out.append((pkg, load_rqt_mrta(f)))
            except ConfigError as exc:
                self.problems.append(str(exc))
        return out

    def architectures(self) -> list[tuple[Package, ArchitectureFile]]:
        return [(p, m) for p, m in self._models("architecture") if isinstance(m, ArchitectureFile)]

    def applications(self, only: Callable[[Package], bool] | None = None
                     ) -> list[tuple[Package, ApplicationFile]]:
        """Every package's application model, or those of the packages `only` accepts (read
        before their files are: a derived 100-robot package's is ≈ 11 MB of XML, 1.6 CPU-s)."""
        return [(p, m) for p, m in self._models("application", only)
                if isinstance(m, ApplicationFile)]

    def _named(self, name: str, kind: str, items: list) -> tuple[Package, object]:
        for pkg, model in items:
            if name == pkg.name or name.lower() == model.name.lower():
                return pkg, model
        names = [p.name for p, _ in items]
        # a package that exists but failed to load: say why instead of "unknown"
        for problem in self.problems:
            if name in problem:
                raise ConfigError(f"{kind} {name!r} did not load: {problem}")
        raise ConfigError(f"unknown {kind} {name!r}" + did_you_mean(name, names)
                          + f" (known: {', '.join(names) or 'none'})")

    WORLD_SUFFIXES = (".yaml", ".yml", ".map")

    def worlds(self) -> dict[str, Path]:
        """World name → file, from every package's `worlds/` folder (first package wins)."""
        out: dict[str, Path] = {}
        for pkg in self.packages.values():
            folder = pkg.path / "worlds"
            if folder.is_dir():
                for f in sorted(folder.iterdir()):
                    if f.suffix in self.WORLD_SUFFIXES and f.is_file():
                        out.setdefault(f.stem, f)
        return out

    def world(self, name: str) -> Path:
        worlds = self.worlds()
        if name not in worlds:
            raise ConfigError(f"no such world file or registered world: {name!r}"
                              + did_you_mean(name, worlds)
                              + f" (registered: {', '.join(sorted(worlds)) or 'none'})")
        return worlds[name]

    def architecture(self, name: str) -> tuple[Package, ArchitectureFile]:
        """The architecture package named `name` — read alone, as `application` reads its
        package (every package's file took 0.1 CPU-s a generated package) — or else the one
        whose architecture is called so."""
        named = [(p, m) for p, m in self._models("architecture", lambda p: p.name == name)
                 if isinstance(m, ArchitectureFile)]
        if named:
            return named[0]
        return self._named(name, "architecture", self.architectures())

    def application(self, name: str) -> tuple[Package, ApplicationFile]:
        """The application package named `name` — read alone — or else the one whose
        application is called so (every package's file read)."""
        named = self.applications(lambda p: p.name == name)
        if named:
            return named[0]
        return self._named(name, "application", self.applications())

    def architecture_of(self, app: ApplicationFile) -> tuple[Package, ArchitectureFile]:
        """The architecture an application names; unknown, a ConfigError at its
        `<architecture>` element (file and line), not a bare "unknown architecture"."""
        try:
            return self.architecture(app.architecture)
        except ConfigError as exc:
            raise ConfigError(exc.detail, file=app.source, line=app.architecture_line,
                              element="<architecture>") from None


# ------------------------------------------------------------------- Gerkey–Matarić filter

_ALIASES = {
    "st": "ST", "single-task": "ST", "singletask": "ST",
    "mt": "MT", "multi-task": "MT", "multitask": "MT",
    "sr": "SR", "single-robot": "SR", "singlerobot": "SR",
    "mr": "MR", "multi-robot": "MR", "multirobot": "MR",
    "ia": "IA", "instantaneous-assignment": "IA", "instantaneous": "IA",
    "ta": "TA", "time-extended-assignment": "TA", "time-extended": "TA",
}


def taxonomy_value(axis: str, value: str) -> str:
    """`single-task`, `Single Task`, `st` → `ST`, checked against the axis it is given for."""
    key = re.sub(r"[\s_]+", "-", value.strip().lower())
    code = _ALIASES.get(key) or _ALIASES.get(key.replace("-", ""))
    allowed = {"robots": ROBOT_TYPES, "tasks": TASK_TYPES, "allocations": ALLOCATION_TYPES}[axis]
    if code not in allowed:
        raise ConfigError(f"--{axis} {value!r}: expected one of {', '.join(allowed)} "
                          f"(or their long names, e.g. single-task)")
    return code


def matches_taxonomy(arch: ArchitectureFile, robots: str | None, tasks: str | None,
                     allocations: str | None) -> bool:
    return ((robots is None or arch.robots_type == robots)
            and (tasks is None or arch.tasks_type == tasks)
            and (allocations is None or arch.allocations_type == allocations))
