"""What `mrta demo` needs of an application package beyond rqt_mrta's files: the simulation
launch file of the mission it runs (and the layers file that launch names, when the
architecture has no template for it).

`mrta demo --application PKG` runs the mission registered (under `mrta.missions`) for PKG or for
a package PKG depends on, by starting PKG's own copy of that mission's launch file (the
simulator and one agent per robot on simulation time: `Mission.launch`). The wizard wrote the
robots' launch files only, so an application it made could not run there (issue 51, the
newcomer's list) — patrol_murdoch's two extra files were written by hand. They are derived here
from the mission package's own launch file, which is the one description of the mission's
world the framework has: its arguments and environment kept, the simulator node's `--robot`
options replaced by this package's robots (a robot named as one of the mission's keeps its
start), and its agents replaced by this package's — each robot's include as the robot's own
launch file has it, plus the `agent_args` the mission's agents take (`--sim-time`). Its layers
file, when the package has none (MURDOCH's template has no layers file), is the mission
package's, copied: the layers are the mission's (patrol's border, its report point).

The core knows no mission: it reads the group's entry points by name and the loaded hook's
`launch` and `instances` (mrta_supervisor.mission.Mission), as the runner does. A mission whose
packages are derived from instance files (delivery: robots, starts and tasks are the
instance's) is refused, naming the command that derives them.
"""

from __future__ import annotations

import copy
import re

from lxml import etree

from ..architectures import TEAM_ENV, architecture
from ..errors import ConfigError
from ..installed import entry_points
from ..yamlfile import did_you_mean
from .model import ApplicationFile
from .registry import Registry

MISSIONS_GROUP = "mrta.missions"
_ROBOT = re.compile(r"--robot(?:=|\s+)(\S+)")
_FIND = re.compile(r"^\$\(find ([A-Za-z0-9_]+)\)/(.+)$")
AGENT_ARGS = "agent_args"
LAYERS_ARG = "layers_params"


def registered_missions() -> list[str]:
    """The names missions are registered under: the application packages that have one."""
    return sorted({ep.name for ep in entry_points(group=MISSIONS_GROUP)})


def _hook(name: str):
    eps = entry_points(group=MISSIONS_GROUP).select(name=name)
    if not eps:
        known = registered_missions()
        raise ConfigError(f"mission {name!r}: no application registers it under "
                          f"{MISSIONS_GROUP}; registered: {', '.join(known) or 'none'}"
                          + did_you_mean(name, known))
    return next(iter(eps)).load()


def check_mission(name: str) -> str:
    """`name` if a package for that mission can be made here ("" too: none); else a
    ConfigError saying why — unknown, or a mission whose packages are derived from an
    instance (`Mission.instances`: delivery's robots, starts and tasks are an instance's)."""
    if not name:
        return name
    hook = _hook(name)
    try:
        from_instances = hook.instances
    except AttributeError:
        raise ConfigError(f"{MISSIONS_GROUP} entry point {name!r} is not a mission "
                          "(mrta_supervisor.mission.Mission)") from None
    if from_instances:
        raise ConfigError(f"the {name} mission runs packages derived from an instance file, "
                          f"not made here: mrta demo --application {name} --instance FILE "
                          "--architecture ARCH (README, \"Instances\")")
    return name


def check_pairing(mission: str, arch: str) -> None:
    """ConfigError when architecture `arch` cannot run `mission` ("": none) — a mission of
    continuous tasks under an architecture of routes (Architecture.mission_refusal): the
    package made would run with idle robots and no dispatcher (issue 51)."""
    if not mission:
        return
    refusal = architecture(arch).mission_refusal(mission, bool(_hook(mission).continuous))
    if refusal:
        raise ConfigError(refusal)


def mission_launch(name: str) -> str:
    """The launch file a package made for mission `name` holds (`Mission.launch`)."""
    return str(_hook(name).launch)


def mission_files(app: ApplicationFile, package: str, mission: str,
                  files: dict[str, bytes], registry: Registry | None = None
                  ) -> dict[str, bytes]:
    """The files to add to `files` (a package being made, relative path → bytes) so that
    `mrta demo --application PACKAGE` runs it as `mission` (module docstring); {} for no
    mission ("")."""
    if not check_mission(mission):
        return {}
    launch_name = mission_launch(mission)
    if not launch_name or f"launch/{launch_name}" in files:
        return {}
    reg = registry or Registry()
    source = reg.find(mission).path / "launch" / launch_name
    try:
        theirs = etree.parse(str(source), etree.XMLParser(remove_blank_text=True)).getroot()
    except (OSError, etree.XMLSyntaxError) as exc:
        raise ConfigError(f"the {mission} mission's launch file cannot be read: {exc}",
                          file=str(source)) from None
    agents = [e for e in theirs if e.tag == "include"
              and any(a.get("name") == "robot_id" for a in e.iterfind("arg"))]
    if not agents:
        raise ConfigError("no agent include (an <include> with a robot_id arg) to take the "
                          "robots' from", file=str(source))
    agent_args = _arg(agents[0], AGENT_ARGS)
    robots = [r.id for r in app.robots]
    root = etree.Element("launch")
    for e in theirs:
        if e in agents:
            continue  # ours, below
        e = _copy(e)
        if e.tag == "env" and e.get("name") == TEAM_ENV:
            e.set("value", ",".join(robots))
        elif e.tag == "node" and _ROBOT.search(e.get("args", "")):
            e.set("args", _with_robots(e.get("args", ""), robots))
        root.append(e)
    added: dict[str, bytes] = {}
    for la in app.launches:
        for inc in la.includes:
            ie = etree.SubElement(root, "include", file=inc.file)
            names = set()
            for arg in inc.args:
                value = arg.value if arg.value is not None else (arg.default or "")
                etree.SubElement(ie, "arg", name=arg.name, value=value)
                names.add(arg.name)
                if arg.name == LAYERS_ARG:
                    added.update(_layers(value, package, files, agents[0], reg))
            if agent_args is not None and AGENT_ARGS not in names:
                etree.SubElement(ie, "arg", name=AGENT_ARGS, value=agent_args)
    etree.indent(root, space="  ")
    head = (f"<!-- The {mission} mission with {package}'s robots: derived by `mrta app new` from "
            f"{mission}'s {launch_name}\n     (the simulator; one agent per robot on simulation "
            f"time). mrta demo, application {package};\n     or mrta launch {package} "
            f"{launch_name} [speed:=2] -->\n")
    added[f"launch/{launch_name}"] = (b'<?xml version="1.0"?>\n' + head.encode()
                                      + etree.tostring(root, encoding="UTF-8", pretty_print=True))
    return added


def _copy(e):
    out = copy.deepcopy(e)
    out.tail = None
    return out


def _arg(include, name: str) -> str | None:
    return next((a.get("value", a.get("default")) for a in include.iterfind("arg")
                 if a.get("name") == name), None)


def _with_robots(args: str, robots: list[str]) -> str:
    """The simulator's args with `--robot` options for `robots` in place of the mission's: a
    robot named as one of them keeps its start (ID=x,y,θ), another is placed by the world."""
    starts = {m.group(1).split("=", 1)[0]: m.group(1) for m in _ROBOT.finditer(args)}
    ours = " ".join(f"--robot {starts.get(r, r)}" for r in robots)
    first = _ROBOT.search(args)
    rest = _ROBOT.sub("", args[first.end():])
    return re.sub(r"\s+", " ", f"{args[:first.start()]}{ours}{rest}").strip()


def _layers(value: str, package: str, files: dict[str, bytes], agent, reg: Registry
            ) -> dict[str, bytes]:
    """The mission's layers file, copied to where the package's agents read theirs, when the
    package has none there."""
    ours = _FIND.match(value)
    if ours is None or ours.group(1) != package or ours.group(2) in files:
        return {}
    theirs = _FIND.match(_arg(agent, LAYERS_ARG) or "")
    if theirs is None:
        return {}
    source = reg.find(theirs.group(1)).path / theirs.group(2)
    try:
        body = source.read_bytes()
    except OSError as exc:
        raise ConfigError(f"cannot read the mission's layers file: {exc.strerror}",
                          file=str(source)) from None
    name = ours.group(2).rsplit("/", 1)[-1].removesuffix(".yaml")
    head = (f"# {name}: the {theirs.group(1)} mission's layers' parameters, copied by `mrta app "
            f"new` from {theirs.group(1)}/{theirs.group(2)}\n")
    lines = body.splitlines(keepends=True)
    while lines and lines[0].startswith(b"#"):  # their header: ours says where it came from
        lines.pop(0)
    return {ours.group(2): head.encode() + b"".join(lines)}
