"""The roslaunch XML subset the templates and reference files use, evaluated to a list of nodes.

Substitutions are parsed into objects once (`$(arg x)`, `$(find pkg)`, `$(env X)`,
`$(optenv X default)`), never evaluated as text tricks; an unknown one, a missing argument, an
unknown tag or attribute is a ConfigError with file and line. Nodes map `pkg/type` to an executable
registered in the `mrta.executables` entry-point group (a click command), e.g. `robot_agent/agent`.
`param` and `rosparam load` have no parameter server to go to: they are collected per node and
handed to it as JSON in the `MRTA_NODE_PARAMS` environment variable.

Bounded, unlike roslaunch: includes nest at most MAX_DEPTH deep, a launch expands at most
MAX_INCLUDES includes and MAX_NODES nodes, and a substituted value is at most MAX_TEXT
characters. Twenty files of 200 bytes, each including the next twice, are a million includes
(roslaunch, and this evaluator before the bounds, ran on for minutes); `$(arg a)$(arg a)`
doubled through fifty args is a petabyte string. Either is refused at once, naming the chain of
includes. An error inside an included file names where it was included from.
"""

from __future__ import annotations

import importlib.metadata
import os
import re
import shlex
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable


from ..errors import ConfigError
from ..installed import entry_points
from ..yamlfile import did_you_mean

EXECUTABLES_GROUP = "mrta.executables"
MAX_DEPTH = 16        # includes within includes (the shipped missions nest 2 deep)
MAX_INCLUDES = 5_000  # includes evaluated in one launch (one per robot and per agent: 2,500 robots)
MAX_NODES = 1_000     # processes one launch starts
MAX_TEXT = 100_000    # characters of one attribute after substitution

_ATTRS = {
    "launch": set(),
    "arg": {"name", "default", "value", "doc"},
    "include": {"file", "ns", "pass_all_args"},
    "group": {"ns"},
    "node": {"name", "pkg", "type", "args", "output", "required", "respawn", "ns", "cwd"},
    "param": {"name", "value", "type"},
    "rosparam": {"command", "file", "ns", "param"},
    "env": {"name", "value"},
    "remap": {"from", "to"},
}
_CHILDREN = {
    "launch": {"arg", "include", "group", "node", "env", "param", "rosparam", "remap"},
    "group": {"arg", "include", "group", "node", "env", "param", "rosparam", "remap"},
    "include": {"arg", "env"},
    "node": {"param", "rosparam", "env", "remap"},
}
_REQUIRED = {"arg": ("name",), "include": ("file",), "node": ("pkg", "type"),
             "param": ("name",), "env": ("name", "value"), "remap": ("from", "to")}
_SUB = re.compile(r"\$\(([^()]*)\)")
_KINDS = {"arg": 1, "find": 1, "env": 1, "optenv": (1, 2)}


@dataclass(frozen=True)
class Text:
    text: str


@dataclass(frozen=True)
class Substitution:
    kind: str
    args: tuple[str, ...]


def parse_substitutions(text: str, where: Callable[[str], ConfigError]) -> list:
    parts: list = []
    pos = 0
    for m in _SUB.finditer(text):
        if m.start() > pos:
            parts.append(Text(text[pos:m.start()]))
        words = m.group(1).split()
        if not words or words[0] not in _KINDS:
            raise where(f"unknown substitution $({m.group(1)}); expected "
                        + ", ".join(f"$({k} …)" for k in _KINDS)
                        + (did_you_mean(words[0], _KINDS) if words else ""))
        n = _KINDS[words[0]]
        lo, hi = n if isinstance(n, tuple) else (n, n)
        if not lo <= len(words) - 1 <= hi:
            raise where(f"$({m.group(1)}): {words[0]} takes {lo if lo == hi else f'{lo}-{hi}'} "
                        "argument(s)")
        parts.append(Substitution(words[0], tuple(words[1:])))
        pos = m.end()
    if "$(" in text[pos:]:
        raise where(f"unterminated substitution in {text!r}")
    if pos < len(text):
        parts.append(Text(text[pos:]))
    return parts


@dataclass
class NodeSpec:
    name: str          # with its namespace, e.g. robot1/alliance
    pkg: str
    type: str
    args: list[str]
    env: dict[str, str] = field(default_factory=dict)
    params: dict[str, str] = field(default_factory=dict)
    rosparam_files: list[str] = field(default_factory=list)
    remaps: dict[str, str] = field(default_factory=dict)
    required: bool = False
    file: str = ""
    line: int | None = None

    @property
    def executable(self) -> str:
        return f"{self.pkg}/{self.type}"


class _Scope:
    def __init__(self, file: Path, args: dict[str, str], ns: str, env: dict[str, str]):
        self.file, self.args, self.ns, self.env = file, args, ns, env


class LaunchEvaluator:
    """Evaluates a launch file (and its includes) into NodeSpecs; `find` resolves packages."""

    def __init__(self, find: Callable[[str], Path], environ: dict[str, str] | None = None):
        self.find = find
        self.environ = dict(os.environ if environ is None else environ)
        self.nodes: list[NodeSpec] = []
        self._stack: list[Path] = []  # the files being evaluated, outermost first
        self._sites: list[tuple[Path, int | None]] = []  # where each of them was included
        self._includes = 0
        self._parsed: dict[Path, object] = {}  # a file included many times is parsed once

    def run(self, path: Path, args: dict[str, str]) -> list[NodeSpec]:
        """The nodes of the launch file `path`; ConfigError naming file, line and — for an
        error inside an included file — the chain of includes that led there."""
        try:
            self._file(Path(path), dict(args), "", {})
        except ConfigError as exc:
            if not self._sites:
                raise
            raise ConfigError(f"{exc.detail} (included from {self._chain()})", file=exc.file,
                              line=exc.line, element=exc.element) from None
        return self.nodes

    def _chain(self) -> str:
        """`b.launch:3 ← a.launch:2`: the include sites from the innermost out (at most the
        three innermost and the outermost, so the line stays one line)."""
        sites = [f"{f}:{line}" if line else str(f) for f, line in reversed(self._sites)]
        if len(sites) > 4:
            sites = sites[:3] + [f"… {len(sites) - 4} more"] + sites[-1:]
        return " ← ".join(sites)

    # ------------------------------------------------------------------------ evaluation

    def _err(self, file: Path, el, message: str) -> ConfigError:
        return ConfigError(message, file=str(file), line=el.sourceline if el is not None else None,
                           element=f"<{el.tag}>" if el is not None else None)

    def _file(self, path: Path, given: dict[str, str], ns: str, env: dict[str, str]) -> None:
        resolved = path.resolve()
        if resolved in self._stack:
            raise ConfigError("launch file includes itself", file=str(path))
        root = self._parsed.get(resolved)
        if root is None:
            # imported here: every node process (run_node) imports this module for
            # executables() alone, and lxml costs each of a 100-robot team ≈ 3 MB and 0.05 s
            from .xmlio import parse_xml_file

            root = self._parsed[resolved] = parse_xml_file(path)
        if root.tag != "launch":
            raise self._err(path, root, "the root element must be <launch>")
        self._stack.append(resolved)
        scope = _Scope(path, {}, ns, dict(env))
        declared: set[str] = set()
        for el in root:
            if isinstance(el.tag, str) and el.tag == "arg":
                declared.add(el.get("name", ""))
        unknown = set(given) - declared
        if unknown:
            name = sorted(unknown)[0]
            raise ConfigError(f"argument {name!r} is not declared by this launch file"
                              + did_you_mean(name, declared)
                              + f" (it declares: {', '.join(sorted(declared)) or 'none'})",
                              file=str(path))
        self._children(scope, root, given)
        self._stack.pop()  # on success only: an error's chain is the stack where it happened
        if self._sites:
            self._sites.pop()

    def _check(self, scope: _Scope, el) -> None:
        allowed = _ATTRS[el.tag]
        for a in el.attrib:
            if a not in allowed:
                raise self._err(scope.file, el, f"unexpected attribute {a!r}"
                                + did_you_mean(a, allowed)
                                + f" (allowed: {', '.join(sorted(allowed)) or 'none'})")
        for a in _REQUIRED.get(el.tag, ()):
            if el.get(a) is None:
                raise self._err(scope.file, el, f"missing attribute {a!r}")

    def _sub(self, scope: _Scope, el, text: str | None) -> str:
        if text is None:
            return ""
        out = []
        size = 0
        for part in parse_substitutions(text, lambda m: self._err(scope.file, el, m)):
            piece = part.text if isinstance(part, Text) else self._value(scope, el, part)
            size += len(piece)
            if size > MAX_TEXT:
                raise self._err(scope.file, el, f"a value longer than {MAX_TEXT:,} characters "
                                "after substitution")
            out.append(piece)
        return "".join(out)

    def _value(self, scope: _Scope, el, part: Substitution) -> str:
        if part.kind == "arg":
            name = part.args[0]
            if name not in scope.args:
                raise self._err(scope.file, el, f"$(arg {name}): no such argument in scope"
                                + did_you_mean(name, scope.args))
            return scope.args[name]
        if part.kind == "find":
            try:
                return str(self.find(part.args[0]))
            except ConfigError as exc:
                raise self._err(scope.file, el, f"$(find {part.args[0]}): {exc}") from None
        if part.kind == "env":
            if part.args[0] not in self.environ:
                raise self._err(scope.file, el, f"$(env {part.args[0]}): variable not set")
            return self.environ[part.args[0]]
        # optenv
        return self.environ.get(part.args[0], part.args[1] if len(part.args) > 1 else "")

    def _children(self, scope: _Scope, parent, given: dict[str, str]) -> None:
        allowed = _CHILDREN[parent.tag]
        for el in parent:
            if not isinstance(el.tag, str):
                continue
            if el.tag not in allowed:
                raise self._err(scope.file, el, f"unexpected element inside <{parent.tag}>"
                                + did_you_mean(el.tag, allowed)
                                + f" (expected: {', '.join(f'<{t}>' for t in sorted(allowed))})")
            self._check(scope, el)
            getattr(self, f"_{el.tag}")(scope, el, given)

    def _arg(self, scope: _Scope, el, given: dict[str, str]) -> None:
        name = el.get("name")
        if el.get("value") is not None:
            if name in given:
                raise self._err(scope.file, el, f"argument {name!r} has a fixed value and cannot "
                                "be set from outside")
            scope.args[name] = self._sub(scope, el, el.get("value"))
        elif name in given:
            scope.args[name] = given[name]
        elif el.get("default") is not None:
            scope.args[name] = self._sub(scope, el, el.get("default"))
        else:
            raise self._err(scope.file, el, f"required argument {name!r} was not given "
                            f"(pass {name}:=VALUE)")

    def _group(self, scope: _Scope, el, given) -> None:
        ns = self._sub(scope, el, el.get("ns")).strip("/")
        inner = _Scope(scope.file, scope.args, "/".join(p for p in (scope.ns, ns) if p),
                       dict(scope.env))
        self._children(inner, el, given)

    def _env(self, scope: _Scope, el, given) -> None:
        scope.env[el.get("name")] = self._sub(scope, el, el.get("value"))

    def _include(self, scope: _Scope, el, given) -> None:
        file = Path(self._sub(scope, el, el.get("file")))
        if not file.is_file():
            raise self._err(scope.file, el, f"included file {file} does not exist")
        args, env = {}, dict(scope.env)
        if el.get("pass_all_args", "false").lower() == "true":
            args.update(scope.args)
        for child in el:
            if not isinstance(child.tag, str):
                continue
            if child.tag not in _CHILDREN["include"]:
                raise self._err(scope.file, child, "unexpected element inside <include>; "
                                "expected <arg> or <env>" + did_you_mean(child.tag, ["arg", "env"]))
            self._check(scope, child)
            if child.tag == "arg":
                if child.get("value") is None:
                    raise self._err(scope.file, child, "an <arg> inside <include> needs value=")
                args[child.get("name")] = self._sub(scope, child, child.get("value"))
            else:
                env[child.get("name")] = self._sub(scope, child, child.get("value"))
        ns = self._sub(scope, el, el.get("ns")).strip("/")
        self._includes += 1
        if len(self._stack) >= MAX_DEPTH:
            raise self._err(scope.file, el, f"includes nest more than {MAX_DEPTH} deep")
        if self._includes > MAX_INCLUDES:
            raise self._err(scope.file, el, f"more than {MAX_INCLUDES:,} includes in one "
                            "launch (files that include others several times multiply)")
        self._sites.append((scope.file, el.sourceline))
        self._file(file, args, "/".join(p for p in (scope.ns, ns) if p), env)

    def _param(self, scope: _Scope, el, given) -> None:
        pass  # top-level params have no node to go to; accepted for compatibility

    def _rosparam(self, scope: _Scope, el, given) -> None:
        if el.get("command", "load") != "load":
            raise self._err(scope.file, el, f"rosparam command {el.get('command')!r} is not "
                            "supported; only command=\"load\"")

    def _remap(self, scope: _Scope, el, given) -> None:
        pass  # Zenoh keys are not remapped; accepted so reference files load

    def _args(self, scope: _Scope, el) -> list[str]:
        text = self._sub(scope, el, el.get("args"))
        try:
            return shlex.split(text)
        except ValueError as exc:  # "No closing quotation"
            raise ConfigError(f"args={text!r:.80}: {str(exc).lower()}", file=str(scope.file),
                              line=el.sourceline, element="<node>") from None

    def _node(self, scope: _Scope, el, given) -> None:
        ns = "/".join(p for p in (scope.ns, self._sub(scope, el, el.get("ns")).strip("/")) if p)
        name = self._sub(scope, el, el.get("name")) or el.get("type")
        spec = NodeSpec(name="/".join(p for p in (ns, name) if p),
                        pkg=self._sub(scope, el, el.get("pkg")),
                        type=self._sub(scope, el, el.get("type")),
                        args=self._args(scope, el),
                        env=dict(scope.env),
                        required=el.get("required", "false").lower() == "true",
                        file=str(scope.file), line=el.sourceline)
        for child in el:
            if not isinstance(child.tag, str):
                continue
            if child.tag not in _CHILDREN["node"]:
                raise self._err(scope.file, child, "unexpected element inside <node>"
                                + did_you_mean(child.tag, _CHILDREN["node"]))
            self._check(scope, child)
            if child.tag == "param":
                spec.params[child.get("name")] = self._sub(scope, child, child.get("value"))
            elif child.tag == "rosparam":
                self._rosparam(scope, child, given)
                if child.get("file"):
                    spec.rosparam_files.append(self._sub(scope, child, child.get("file")))
            elif child.tag == "env":
                spec.env[child.get("name")] = self._sub(scope, child, child.get("value"))
            else:
                spec.remaps[self._sub(scope, child, child.get("from"))] = \
                    self._sub(scope, child, child.get("to"))
        if len(self.nodes) >= MAX_NODES:
            raise self._err(scope.file, el, f"more than {MAX_NODES:,} nodes in one launch")
        self.nodes.append(spec)


def executables() -> dict[str, importlib.metadata.EntryPoint]:
    return {ep.name: ep for ep in entry_points(group=EXECUTABLES_GROUP)}


def check_executables(nodes: list[NodeSpec]) -> None:
    known = executables()
    for n in nodes:
        if n.executable not in known:
            raise ConfigError(f"node {n.name!r}: no executable registered for pkg={n.pkg!r} "
                              f"type={n.type!r}" + did_you_mean(n.executable, known)
                              + f" (registered: {', '.join(sorted(known))})",
                              file=n.file, line=n.line, element="<node>")
