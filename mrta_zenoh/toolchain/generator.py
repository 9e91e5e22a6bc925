"""Turn a user's answers into an application package, written all or nothing.

The answers are the same whether they come from the terminal wizard or from an `--answers` YAML
file (documented in docs/toolchain.md), so both paths share every check below.
"""

from __future__ import annotations

import dataclasses
import re
from dataclasses import dataclass, field
from pathlib import Path

import yaml
from lxml import etree

from ..architectures import TEAM_ENV
from ..errors import ConfigError
from ..files import write_folder
from ..keys import KeyExprError, is_id, normalize_robot_id
from ..yamlfile import YamlDoc, did_you_mean, load_yaml
from .checks import layers_config_id, read_layer_sections
from .missionfiles import check_mission, check_pairing
from .model import (ApplicationFile, ArchitectureFile, Config, Launch, LaunchArg, LaunchInclude,
                    Params, RobotEntry)
from .registry import Package
from .templates import instantiate, to_data
from .xmlio import to_xml

PACKAGE_NAME = re.compile(r"^[a-z][a-z0-9_]*$")
VERSION = re.compile(r"^\d+\.\d+\.\d+$")
EMAIL = re.compile(r"^[^@\s]+@[^@\s]+\.[A-Za-z]{2,}$")


@dataclass
class Answers:
    package: str
    name: str
    architecture: str
    robots: dict[str, list[str]]
    configs: dict = field(default_factory=dict)
    version: str = "1.0.0"
    description: str = ""
    maintainer: str = ""
    email: str = ""
    license: str = "Apache-2.0"
    depends: list[str] = field(default_factory=list)
    # the mission (registered under mrta.missions) `mrta demo` runs it as: a dependency, and
    # its simulation launch file derived from that mission's (missionfiles.py); "" none
    mission: str = ""


def check_general(a: Answers) -> None:
    """The wizard's first page: each rule the dissertation's GUI enforced, with the value at fault."""
    if not PACKAGE_NAME.match(a.package or ""):
        raise ConfigError(f"package {a.package!r}: use lower-case letters, digits and '_', "
                          "starting with a letter")
    if not VERSION.match(a.version or ""):
        raise ConfigError(f"version {a.version!r}: expected MAJOR.MINOR.PATCH, e.g. 1.0.0")
    if not a.name.strip():
        raise ConfigError("name: the application needs a name")
    if not a.maintainer.strip():
        raise ConfigError("maintainer: give the maintainer's name")
    if not EMAIL.match(a.email or ""):
        raise ConfigError(f"email {a.email!r}: not a valid e-mail address")
    if not a.license.strip():
        raise ConfigError("license: give a licence, e.g. Apache-2.0 or BSD")
    if not a.robots:
        raise ConfigError("robots: the application needs at least one robot")
    for rid, tasks in a.robots.items():
        try:
            normalize_robot_id(rid)
        except KeyExprError as exc:
            raise ConfigError(f"robots: {exc}") from None
        if not tasks:
            raise ConfigError(f"robots/{rid}: give at least one task this robot can do")
        for t in tasks:
            if not is_id(str(t)):
                raise ConfigError(f"robots/{rid}: task id {t!r} must be one key chunk "
                                  "(letters, digits, '_', '-', '.')")


_ANSWER_KEYS = ("package", "name", "architecture", "robots", "configs", "version", "description",
                "maintainer", "email", "license", "depends", "mission")


def load_answers(path: Path) -> tuple[Answers, YamlDoc]:
    doc = load_yaml(path, aliases=True)
    d = doc.data
    if not isinstance(d, dict):
        raise doc.error((), "an answers file is a mapping (see docs/toolchain.md)")
    for key in d:
        if key not in _ANSWER_KEYS:
            raise doc.error((key,), f"unexpected key {key!r}" + did_you_mean(key, _ANSWER_KEYS))
    for key in ("package", "name", "architecture", "robots", "maintainer", "email"):
        if key not in d:
            raise doc.error((), f"missing mandatory key {key!r}")
    robots = d["robots"]
    if not isinstance(robots, dict) or not all(isinstance(v, list) for v in robots.values()):
        raise doc.error(("robots",), "robots maps each robot id to the list of its task ids")
    a = Answers(package=str(d["package"]), name=str(d["name"]),
                architecture=str(d["architecture"]),
                robots={normalize_robot_id(str(k)) if isinstance(k, str) else str(k):
                        [str(t) for t in v] for k, v in robots.items()},
                configs=d.get("configs") or {}, version=str(d.get("version", "1.0.0")),
                description=str(d.get("description", "")), maintainer=str(d["maintainer"]),
                email=str(d["email"]), license=str(d.get("license", "Apache-2.0")),
                depends=[str(x) for x in d.get("depends") or []],
                mission=str(d.get("mission") or ""))
    try:
        check_mission(a.mission)
        check_pairing(a.mission, a.architecture)
    except ConfigError as exc:
        raise doc.error(("mission",), str(exc)) from None
    try:
        check_general(a)
    except ConfigError as exc:
        key = str(exc).split(" ", 1)[0].split(":", 1)[0].split("/", 1)[0]
        raise doc.error((key,) if key in d else (), str(exc)) from None
    return a, doc


def _where_to_path(where: str) -> tuple:
    parts: list = []
    for chunk in where.split("/"):
        m = re.match(r"^(.*?)((?:\[\d+\])*)$", chunk)
        parts.append(m.group(1))
        parts.extend(int(i) for i in re.findall(r"\[(\d+)\]", m.group(2)))
    return tuple(p for p in parts if p != "")


def build_application(arch_pkg: Package, arch: ArchitectureFile, a: Answers,
                      doc: YamlDoc | None = None) -> tuple[ApplicationFile, dict[str, bytes]]:
    """The application model and every file of its package (relative path → bytes)."""
    check_general(a)
    configs: list[Config] = []
    files: dict[str, bytes] = {}
    known = {c.id for c in arch.configs}
    for key in a.configs:
        if key not in known:
            raise _located(doc, ("configs", key), f"configs/{key}: the architecture has no config "
                           f"{key!r}" + did_you_mean(key, known) + f" (it has: {', '.join(sorted(known))})")
    for c in arch.configs:
        given = a.configs.get(c.id)
        try:
            if c.id == arch.config_id:
                per_robot = given or {}
                if not isinstance(per_robot, dict):
                    raise ConfigError(f"configs/{c.id}: expected a mapping robot id → parameters")
                for rid in per_robot:
                    if rid not in a.robots:
                        raise ConfigError(f"configs/{c.id}/{rid}: not one of the robots "
                                          f"({', '.join(a.robots)})")
                for rid, tasks in a.robots.items():
                    filled = instantiate(c, per_robot.get(rid), f"{rid}_{c.id}",
                                         f"configs/{c.id}/{rid}", robot_tasks=tasks)
                    configs.append(filled)
            else:
                configs.append(instantiate(c, given, c.id, f"configs/{c.id}"))
        except ConfigError as exc:
            where = str(exc).split(":", 1)[0]
            raise _located(doc, _where_to_path(where), str(exc)) from None
    for cfg in configs:
        files[f"config/{cfg.id}.yaml"] = _yaml(cfg, a, arch)
    launches: list[Launch] = []
    template = arch.launch(arch.launch_id) if arch.launch_id else None
    if template is not None:
        for rid in a.robots:
            la = Launch(f"{rid}_{template.id}", [
                LaunchInclude(_subst(inc.file, rid, a.package),
                              [LaunchArg(arg.name, _subst(arg.value, rid, a.package),
                                         _subst(arg.default, rid, a.package)) for arg in inc.args])
                for inc in template.includes])
            launches.append(la)
            files[f"launch/{la.id}.launch"] = _launch_xml(la, list(a.robots))
        files[f"launch/{a.package}.launch"] = _launch_all(a.package, launches)
    app = ApplicationFile(arch_pkg.name, a.name,
                          [RobotEntry(r, list(t)) for r, t in a.robots.items()], configs, launches)
    files["rqt_mrta.xml"] = to_xml(app)
    files["package.xml"] = _package_xml(a, arch_pkg.name)
    return app, files


def _stub(arch_pkg: Package, a: Answers) -> ApplicationFile:
    return ApplicationFile(arch_pkg.name, a.name,
                           [RobotEntry(r, list(t)) for r, t in a.robots.items()])


def without_layers(arch_pkg: Package, arch: ArchitectureFile, a: Answers,
                   doc: YamlDoc | None = None) -> tuple[str | None, dict[str, bytes]]:
    """The layers file's config id (None when the architecture has no contract) and the
    package's files without it: the robots' and the tasks' files say which plugins run."""
    layers_id = layers_config_id(_stub(arch_pkg, a))
    without = dataclasses.replace(arch, configs=[c for c in arch.configs if c.id != layers_id])
    others = {c.id for c in without.configs}  # an unknown config is the full build's to report
    _, files = build_application(arch_pkg, without, dataclasses.replace(
        a, configs={k: v for k, v in a.configs.items() if k in others}), doc)
    return layers_id, files


def restrict_layers(arch_pkg: Package, arch: ArchitectureFile, a: Answers,
                    doc: YamlDoc | None = None) -> ArchitectureFile:
    """`arch` with its layers-file template holding only the sections some robot's plugins
    read (Architecture.layer_sections, from the robot and tasks files these answers make) or
    that the answers set: a patrol without a border task is not asked for, and does not get,
    BorderProtection parameters, which every agent would then warn nobody reads. Unchanged
    when the architecture cannot say."""
    layers_id, files = without_layers(arch_pkg, arch, a, doc)
    layers = arch.config(layers_id) if layers_id else None
    if layers is None:
        return arch
    read = read_layer_sections(files, _stub(arch_pkg, a))
    if read is None:
        return arch
    given = a.configs.get(layers_id)
    keep = read | (set(given) if isinstance(given, dict) else set())
    kept = [c for c in layers.children if not isinstance(c, Params) or c.name in keep]
    return dataclasses.replace(arch, configs=[
        dataclasses.replace(c, children=kept) if c.id == layers_id else c for c in arch.configs])


def _located(doc: YamlDoc | None, path: tuple, message: str) -> ConfigError:
    if doc is None:
        return ConfigError(message)
    return ConfigError(message, file=str(doc.path), line=doc.line(path))


def _subst(text: str | None, robot_id: str, package: str) -> str | None:
    if text is None:
        return None
    return text.replace("@robot_id@", robot_id).replace("@package@", package)


def _yaml(cfg: Config, a: Answers, arch: ArchitectureFile) -> bytes:
    head = (f"# {cfg.id}: written by `mrta app new` for application {a.name!r} "
            f"({arch.name} architecture)\n")
    return (head + dump_yaml(to_data(cfg))).encode()


def dump_yaml(data: object, **options: object) -> str:
    """`yaml.safe_dump(data, sort_keys=False, allow_unicode=True)`'s text, emitted by libyaml
    (the same bytes — tests/test_delivery.py checks the shipped packages against it — at a
    fraction of the pure-Python emitter's CPU: a 100-robot package's robot files are MBs)."""
    return yaml.dump(data, Dumper=yaml.CSafeDumper, sort_keys=False, allow_unicode=True,
                     **options)


def _launch_xml(la: Launch, team: list[str]) -> bytes:
    root = etree.Element("launch")
    root.append(etree.Comment(" the application's robots: the only teammates its agents count "))
    etree.SubElement(root, "env", name=TEAM_ENV, value=",".join(team))
    for inc in la.includes:
        ie = etree.SubElement(root, "include", file=inc.file)
        for arg in inc.args:
            ae = etree.SubElement(ie, "arg", name=arg.name)
            ae.set("value", arg.value if arg.value is not None else (arg.default or ""))
    etree.indent(root, space="  ")
    return etree.tostring(root, xml_declaration=True, encoding="UTF-8", pretty_print=True)


def _launch_all(package: str, launches: list[Launch]) -> bytes:
    root = etree.Element("launch")
    root.append(etree.Comment(" every robot of the application "))
    for la in launches:
        etree.SubElement(root, "include", file=f"$(find {package})/launch/{la.id}.launch")
    etree.indent(root, space="  ")
    return etree.tostring(root, xml_declaration=True, encoding="UTF-8", pretty_print=True)


def _package_xml(a: Answers, arch_package: str) -> bytes:
    root = etree.Element("package")
    for tag, text in (("name", a.package), ("version", a.version),
                      ("description", a.description or a.name)):
        etree.SubElement(root, tag).text = text
    etree.SubElement(root, "maintainer", email=a.email).text = a.maintainer
    etree.SubElement(root, "license").text = a.license
    for dep in dict.fromkeys([arch_package, *a.depends, *([a.mission] if a.mission else [])]):
        etree.SubElement(root, "run_depend").text = dep
    export = etree.SubElement(root, "export")
    etree.SubElement(export, "rqt_mrta", application="${prefix}/rqt_mrta.xml")
    etree.indent(root, space="  ")
    return etree.tostring(root, xml_declaration=True, encoding="UTF-8", pretty_print=True)


def write_package(files: dict[str, bytes], dest: Path, force: bool = False) -> Path:
    """Write every file or none (mrta_zenoh.files.write_folder); an existing package is
    replaced only with `force`."""
    dest = Path(dest)
    if dest.exists() and not force:
        raise ConfigError(f"{dest} already exists; use --force to replace it")
    write_folder(dest, files)
    return dest
