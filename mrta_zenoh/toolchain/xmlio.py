"""Read and write rqt_mrta XML files (architecture: appendix A; application: appendix B).

Strict: every element must be one the format allows where it stands; anything else is a
ConfigError naming file, line (lxml `sourceline`) and element, saying what was expected and
suggesting the nearest allowed tag. Values are checked here with the very functions the runtime
uses (a monitor's key expression `Topic.key_expr`, its field path `FieldPath.parse`, robot ids
`keys.normalize_robot_id`, task ids `keys.task_chunk`, timeouts and queue sizes against
mrta_zenoh.limits), so what `mrta arch validate` / `mrta app validate` pass, the supervisor and
the mission runner accept, and what they would refuse is refused at load with its line. Indexed tags (`param_0`, `params_5`, `array_1`, `robot_2`)
are read in document order and written back with their position as index.
"""

from __future__ import annotations

import collections
import hashlib
import pickle
import re
import threading
from pathlib import Path

from lxml import etree

from ..errors import ConfigError
from ..fieldpath import FieldPath
from ..keys import task_chunk
from ..limits import DURATION, QUEUE_SIZE
from ..yamlfile import did_you_mean
from .model import (
    ALLOCATION_TYPES, PARAM_TYPES, ROBOT_TYPES, TASK_TYPES, ApplicationFile, ArchitectureFile,
    Array, Config, Launch, LaunchArg, LaunchInclude, Node, Param, Params, RobotEntry, Topic,
)

_INDEXED = re.compile(r"^([a-z_]+?)_(\d+)$")


class _Reader:
    def __init__(self, path: Path):
        self.path = path

    def error(self, el, message: str) -> ConfigError:
        return ConfigError(message, file=str(self.path), line=el.sourceline,
                           element=f"<{el.tag}>")

    def children(self, el, allowed: tuple[str, ...], indexed: tuple[str, ...] = ()) -> list:
        """Element children, each checked against `allowed` plain tags and `indexed` bases."""
        out = []
        for child in el:
            if not isinstance(child.tag, str):
                continue  # comments, processing instructions
            m = _INDEXED.match(child.tag)
            if child.tag in allowed or (m and m.group(1) in indexed):
                out.append(child)
                continue
            options = list(allowed) + [f"{b}_N" for b in indexed]
            raise self.error(child, f"unexpected element inside <{el.tag}>; expected "
                             + ", ".join(f"<{o}>" for o in options)
                             + did_you_mean(re.sub(r"_\d+$", "_N", child.tag), options))
        return out

    def one(self, el, tag: str, required: bool = True):
        found = [c for c in el if c.tag == tag]
        if len(found) > 1:
            raise self.error(found[1], f"<{tag}> appears more than once in <{el.tag}>")
        if not found:
            if required:
                raise self.error(el, f"<{el.tag}> needs a <{tag}> element")
            return None
        return found[0]

    def text(self, el, tag: str, required: bool = True) -> str | None:
        child = self.one(el, tag, required)
        if child is None:
            return None
        if len(child):
            raise self.error(child, f"<{tag}> holds text, not elements")
        return (child.text or "").strip()

    def choice(self, el, tag: str, options: tuple[str, ...]) -> str:
        value = self.text(el, tag)
        if value not in options:
            raise self.error(self.one(el, tag), f"<{tag}> must be one of {', '.join(options)}, "
                             f"got {value!r}")
        return value

    # ---------------------------------------------------------------------------- pieces

    def topic_holder(self, el) -> Topic | None:
        if el is None:
            return None
        self.children(el, ("topic",))
        t = self.one(el, "topic")
        self.children(t, ("name", "type", "field", "queue_size", "timeout"))
        q = self.text(t, "queue_size", required=False)
        to = self.text(t, "timeout", required=False)
        try:
            queue_size = int(q) if q else 10
        except ValueError:
            raise self.error(self.one(t, "queue_size"),
                             f"<queue_size> must be an integer {QUEUE_SIZE.text()}, "
                             f"got {q!r:.40}") from None
        if QUEUE_SIZE.problem(queue_size):
            raise self.error(self.one(t, "queue_size"),
                             f"<queue_size> {QUEUE_SIZE.problem(queue_size)}")
        try:
            timeout = float(to) if to else 1.0
        except ValueError:
            raise self.error(self.one(t, "timeout"), f"<timeout> must be a number of seconds "
                             f"{DURATION.text()}, got {to!r:.40}") from None
        if DURATION.problem(timeout):  # 1e308 s: a `supervise --once` that never returned
            raise self.error(self.one(t, "timeout"), f"<timeout> {DURATION.problem(timeout)}")
        name, type_, fld = self.text(t, "name"), self.text(t, "type"), self.text(t, "field")
        if not name or not type_:
            raise self.error(t, "<topic> needs a non-empty <name> and <type>")
        topic = Topic(name, type_, fld or "", queue_size, timeout, line=t.sourceline)
        try:
            topic.key_expr  # noqa: B018 - checked as the supervisor will subscribe to it
        except ConfigError as exc:
            raise self.error(self.one(t, "name"), str(exc)) from None
        try:
            FieldPath.parse(topic.field)
        except ConfigError as exc:
            raise self.error(self.one(t, "field"), str(exc)) from None
        return topic

    def param_node(self, el) -> Node:
        base = _INDEXED.match(el.tag).group(1)
        if base == "param":
            self.children(el, ("name", "type", "value", "default", "tool_tip"))
            p = Param(name=self.text(el, "name"), type=self.text(el, "type", False),
                      value=self.text(el, "value", False), default=self.text(el, "default", False),
                      tool_tip=self.text(el, "tool_tip", False), line=el.sourceline)
            if not p.name:
                raise self.error(el, "a parameter needs a non-empty <name>")
            if p.type is not None and p.type not in PARAM_TYPES:
                raise self.error(self.one(el, "type"), f"<type> must be one of "
                                 f"{'|'.join(PARAM_TYPES)}, got {p.type!r}"
                                 + did_you_mean(p.type, PARAM_TYPES))
            for what in ("value", "default"):
                v = getattr(p, what)
                problem = type_problem(p.type, v)
                if problem:
                    raise self.error(self.one(el, what), f"<{what}> of {p.name!r}: {problem}")
            return p
        self.children(el, ("name",), ("param", "params", "array"))
        elements = [c for c in el if isinstance(c.tag, str) and c.tag != "name"]
        kids = [self.param_node(c) for c in elements]
        name = self.text(el, "name")
        if base == "array":
            self.no_arrays(elements, kids, f"array {name!r}")
            return Array(name, kids, line=el.sourceline)
        if any(isinstance(k, Array) for k in kids) and not any(
                isinstance(k, Param) and k.name == "size" for k in kids):
            bad = next(e for e, k in zip(elements, kids) if isinstance(k, Array))
            raise self.error(bad, f"an <array> needs a sibling <param> named 'size' (dissertation "
                                  f"§3.1): <params> {name!r} has none")
        return Params(name, kids, line=el.sourceline)

    def no_arrays(self, elements, kids, where: str) -> None:
        """An array is repeated per its sibling `size`, so it must sit inside a <params>."""
        for e, k in zip(elements, kids):
            if isinstance(k, Array):
                raise self.error(e, f"an <array> must be the child of a <params> (dissertation "
                                    f"§3.1), not of {where}")

    def configs(self, el) -> list[Config]:
        if el is None:
            return []
        out = []
        first_line: dict[str, int] = {}
        for c in self.children(el, (), ("config",)):
            self.children(c, ("id",), ("param", "params", "array"))
            config_id = self.text(c, "id")
            if config_id in first_line:  # robots pick their config by id: two would be ambiguous
                raise self.error(c, f"config id {config_id!r} is used twice (first on line "
                                    f"{first_line[config_id]})")
            first_line[config_id] = c.sourceline
            members = [k for k in c if isinstance(k.tag, str) and k.tag != "id"]
            kids = [self.param_node(k) for k in members]
            self.no_arrays(members, kids, f"config {config_id!r}")
            out.append(Config(config_id, kids, line=c.sourceline))
        return out

    def launches(self, el) -> list[Launch]:
        if el is None:
            return []
        out = []
        for la in self.children(el, (), ("launch",)):
            self.children(la, ("id", "includes"))
            includes = []
            inc_el = self.one(la, "includes", required=False)
            if inc_el is not None:
                for inc in self.children(inc_el, (), ("include",)):
                    self.children(inc, ("file", "args"))
                    args = []
                    args_el = self.one(inc, "args", required=False)
                    if args_el is not None:
                        for a in self.children(args_el, (), ("arg",)):
                            self.children(a, ("name", "value", "default"))
                            args.append(LaunchArg(self.text(a, "name"), self.text(a, "value", False),
                                                  self.text(a, "default", False)))
                    includes.append(LaunchInclude(self.text(inc, "file"), args))
            out.append(Launch(self.text(la, "id"), includes))
        return out


def type_problem(type_: str | None, value: str | None) -> str | None:
    """Why `value` is not a valid `type_` literal, or None. Placeholders (@x@, $(…)) pass."""
    if value is None or value == "" or type_ in (None, "string"):
        return None
    if "@" in value or "$(" in value:
        return None
    if type_ == "int":
        try:
            int(value)
        except ValueError:
            return f"expected an int, got {value!r}"
    elif type_ == "double":
        try:
            float(value)
        except ValueError:
            return f"expected a double, got {value!r}"
    elif type_ == "bool" and value.lower() not in ("true", "false", "1", "0"):
        return f"expected a bool (true/false), got {value!r}"
    return None


def parse_xml_file(path: Path):
    """The root element of an XML file; unreadable or malformed → ConfigError with file and line.

    Shared by every XML the toolchain reads (rqt_mrta files, package.xml, launch files)."""
    try:
        parser = etree.XMLParser(remove_blank_text=False, resolve_entities=False, no_network=True)
        return etree.parse(str(path), parser).getroot()
    except OSError as exc:
        raise ConfigError(f"cannot read: {' '.join(str(exc).split())}", file=str(path)) from None
    except etree.XMLSyntaxError as exc:
        line = exc.lineno if exc.lineno else None
        raise ConfigError(f"not well-formed XML: {' '.join(str(exc.msg).split())}",
                          file=str(path), line=line) from None  # libxml2's can span lines


# Models read, by file and content: a process asks for the same few files again and again (the
# registry, the supervisor, the runner, the checks each read the application and its
# architecture; the fast tier read them ≈ 1,000 times, 6 CPU-s). Kept pickled: unpickling is
# 6-10× cheaper than reading, and every caller gets its own copy to change.
_READ_MAX = 64                # files kept
_READ_SIZE_MAX = 1 << 20      # bytes: a derived 100-robot package's 11 MB is read once anyway
_read: collections.OrderedDict[tuple[str, bytes], bytes] = collections.OrderedDict()
_read_lock = threading.Lock()


def load_rqt_mrta(path: Path | str) -> ArchitectureFile | ApplicationFile:
    """An rqt_mrta.xml file: an architecture (appendix A) or an application (appendix B).

    Read once per content in a process: the same bytes at the same path give a copy of the
    model read first (a file changed on disk is read again: the key is its content's digest)."""
    path = Path(path)
    try:
        data = path.read_bytes()
    except OSError:
        data = None  # parse_xml_file says why, naming the file
    if data is None or len(data) > _READ_SIZE_MAX:
        return _load(path, parse_xml_file(path))
    key = (str(path), hashlib.blake2b(data, digest_size=16).digest())
    with _read_lock:
        kept = _read.get(key)
        if kept is not None:
            _read.move_to_end(key)
    if kept is not None:
        return pickle.loads(kept)
    model = _load(path, parse_xml_file(path))  # lxml reads the file itself: its errors' lines
    try:
        kept_as_read = path.read_bytes() == data  # else changed while read: keep nothing
    except OSError:
        kept_as_read = False
    if kept_as_read:
        with _read_lock:
            _read[key] = pickle.dumps(model, pickle.HIGHEST_PROTOCOL)
            while len(_read) > _READ_MAX:
                _read.popitem(last=False)
    return model


def application_architecture(path: Path | str) -> str | None:
    """The <architecture> an application file names, read up to that element only: a run under
    another architecture sets the application's own package aside, and a derived 100-robot one
    is ≈ 24 MB of XML, ≈ 4 CPU-s to read whole (issue 47, start-up). None when the file's start
    is no application's (or does not parse): `load_rqt_mrta` then reads it and says why."""
    try:
        for _, el in etree.iterparse(str(path), events=("end",), tag="architecture",
                                     resolve_entities=False, no_network=True):
            parent = el.getparent()
            if parent is None or parent.tag != "application" or len(el):
                return None
            root = parent.getparent()
            return (el.text or "").strip() if root is not None and root.tag == "rqt_mrta" \
                and root.getparent() is None else None
    except (OSError, etree.XMLSyntaxError):
        return None
    return None


def _load(path: Path, root) -> ArchitectureFile | ApplicationFile:
    r = _Reader(path)
    if root.tag != "rqt_mrta":
        raise r.error(root, "the root element must be <rqt_mrta>"
                      + did_you_mean(root.tag, ["rqt_mrta"]))
    r.children(root, ("architecture", "application", "configs", "launches", "widgets"))
    arch_el, app_el = r.one(root, "architecture", False), r.one(root, "application", False)
    if (arch_el is None) == (app_el is None):
        raise r.error(root, "<rqt_mrta> holds exactly one of <architecture> or <application>")
    configs = r.configs(r.one(root, "configs", False))
    launches = r.launches(r.one(root, "launches", False))
    widgets = []
    w_el = r.one(root, "widgets", False)
    if w_el is not None:
        for w in r.children(w_el, (), ("widget",)):
            r.children(w, ("plugin_name",))
            widgets.append(r.text(w, "plugin_name"))
    if arch_el is not None:
        return _architecture(r, arch_el, configs, launches, widgets, path)
    if widgets:
        raise r.error(w_el, "<widgets> belongs to architecture files")
    return _application(r, app_el, configs, launches, path)


def _architecture(r: _Reader, el, configs, launches, widgets, path) -> ArchitectureFile:
    r.children(el, ("name", "robots", "tasks", "allocations"))
    robots, tasks, allocs = r.one(el, "robots"), r.one(el, "tasks"), r.one(el, "allocations")
    r.children(robots, ("type", "busy_robots", "idle_robots", "config_id", "launch_id"))
    r.children(tasks, ("type", "incoming_tasks"))
    r.children(allocs, ("type", "allocated_tasks"))
    arch = ArchitectureFile(
        name=r.text(el, "name"),
        robots_type=r.choice(robots, "type", ROBOT_TYPES),
        tasks_type=r.choice(tasks, "type", TASK_TYPES),
        allocations_type=r.choice(allocs, "type", ALLOCATION_TYPES),
        busy_robots=r.topic_holder(r.one(robots, "busy_robots", False)),
        idle_robots=r.topic_holder(r.one(robots, "idle_robots", False)),
        incoming_tasks=r.topic_holder(r.one(tasks, "incoming_tasks", False)),
        allocated_tasks=r.topic_holder(r.one(allocs, "allocated_tasks", False)),
        config_id=r.text(robots, "config_id", False),
        launch_id=r.text(robots, "launch_id", False),
        configs=configs, launches=launches, widgets=widgets, source=str(path))
    if arch.config_id and arch.config(arch.config_id) is None:
        raise r.error(r.one(robots, "config_id"), f"no config has id {arch.config_id!r}"
                      + did_you_mean(arch.config_id, [c.id for c in configs]))
    if arch.launch_id and arch.launch(arch.launch_id) is None:
        raise r.error(r.one(robots, "launch_id"), f"no launch has id {arch.launch_id!r}"
                      + did_you_mean(arch.launch_id, [la.id for la in launches]))
    return arch


def _application(r: _Reader, el, configs, launches, path) -> ApplicationFile:
    r.children(el, ("architecture", "name", "robots"))
    robots = []
    first_line: dict[str, int] = {}
    robots_el = r.one(el, "robots", False)
    if robots_el is not None:
        for rb in r.children(robots_el, (), ("robot",)):
            r.children(rb, ("id", "tasks"))
            tasks: list[str] = []
            t_el = r.one(rb, "tasks", False)
            if t_el is not None:
                for t in r.children(t_el, (), ("task",)):
                    r.children(t, ("id",))
                    task = r.text(t, "id")
                    try:
                        task_chunk(task)
                    except ConfigError as exc:
                        raise r.error(r.one(t, "id"), str(exc)) from None
                    if task in tasks:
                        raise r.error(t, f"task {task!r} is listed twice for this robot")
                    tasks.append(task)
            try:
                robot = RobotEntry(r.text(rb, "id"), tasks)  # `/robot1` is robot1 from here on
            except ConfigError as exc:
                raise r.error(r.one(rb, "id"), str(exc)) from None
            if robot.id in first_line:  # one process, one token, one row per robot id
                raise r.error(rb, f"robot {robot.id!r} appears twice (first on line "
                                  f"{first_line[robot.id]})")
            first_line[robot.id] = rb.sourceline
            robots.append(robot)
    return ApplicationFile(r.text(el, "architecture"), r.text(el, "name"), robots, configs,
                           launches, source=str(path),
                           architecture_line=r.one(el, "architecture").sourceline)


# -------------------------------------------------------------------------------- writing

def _sub(parent, tag: str, text: str | None = None):
    el = etree.SubElement(parent, tag)
    if text is not None:
        el.text = text
    return el


def _write_topic(parent, tag: str, topic: Topic | None) -> None:
    if topic is None:
        return
    t = _sub(_sub(parent, tag), "topic")
    _sub(t, "name", topic.name)
    _sub(t, "type", topic.type)
    _sub(t, "field", topic.field)
    _sub(t, "queue_size", str(topic.queue_size))
    _sub(t, "timeout", repr(topic.timeout))


def _write_node(parent, node: Node, index: int) -> None:
    if isinstance(node, Param):
        el = _sub(parent, f"param_{index}")
        _sub(el, "name", node.name)
        for what in ("type", "value", "default", "tool_tip"):
            v = getattr(node, what)
            if v is not None:
                _sub(el, what, v)
        return
    el = _sub(parent, f"{'array' if isinstance(node, Array) else 'params'}_{index}")
    _sub(el, "name", node.name)
    for i, child in enumerate(node.children):
        _write_node(el, child, i)


def _write_common(root, configs: list[Config], launches: list[Launch]) -> None:
    if configs:
        cs = _sub(root, "configs")
        for i, c in enumerate(configs):
            el = _sub(cs, f"config_{i}")
            _sub(el, "id", c.id)
            for j, child in enumerate(c.children):
                _write_node(el, child, j)
    if launches:
        ls = _sub(root, "launches")
        for i, la in enumerate(launches):
            el = _sub(ls, f"launch_{i}")
            _sub(el, "id", la.id)
            incs = _sub(el, "includes")
            for j, inc in enumerate(la.includes):
                ie = _sub(incs, f"include_{j}")
                _sub(ie, "file", inc.file)
                if inc.args:
                    args = _sub(ie, "args")
                    for k, a in enumerate(inc.args):
                        ae = _sub(args, f"arg_{k}")
                        _sub(ae, "name", a.name)
                        if a.value is not None:
                            _sub(ae, "value", a.value)
                        if a.default is not None:
                            _sub(ae, "default", a.default)


def to_xml(model: ArchitectureFile | ApplicationFile) -> bytes:
    root = etree.Element("rqt_mrta")
    if isinstance(model, ArchitectureFile):
        a = _sub(root, "architecture")
        _sub(a, "name", model.name)
        rb = _sub(a, "robots")
        _sub(rb, "type", model.robots_type)
        _write_topic(rb, "busy_robots", model.busy_robots)
        _write_topic(rb, "idle_robots", model.idle_robots)
        if model.config_id is not None:
            _sub(rb, "config_id", model.config_id)
        if model.launch_id is not None:
            _sub(rb, "launch_id", model.launch_id)
        tk = _sub(a, "tasks")
        _sub(tk, "type", model.tasks_type)
        _write_topic(tk, "incoming_tasks", model.incoming_tasks)
        al = _sub(a, "allocations")
        _sub(al, "type", model.allocations_type)
        _write_topic(al, "allocated_tasks", model.allocated_tasks)
        _write_common(root, model.configs, model.launches)
        if model.widgets:
            ws = _sub(root, "widgets")
            for i, w in enumerate(model.widgets):
                _sub(_sub(ws, f"widget_{i}"), "plugin_name", w)
    else:
        a = _sub(root, "application")
        _sub(a, "architecture", model.architecture)
        _sub(a, "name", model.name)
        rbs = _sub(a, "robots")
        for i, r in enumerate(model.robots):
            re_ = _sub(rbs, f"robot_{i}")
            _sub(re_, "id", r.written or r.id)
            ts = _sub(re_, "tasks")
            for j, t in enumerate(r.tasks):
                _sub(_sub(ts, f"task_{j}"), "id", t)
        _write_common(root, model.configs, model.launches)
    etree.indent(root, space="  ")
    return etree.tostring(root, xml_declaration=True, encoding="UTF-8", pretty_print=True)
