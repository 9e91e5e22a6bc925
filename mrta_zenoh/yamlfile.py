"""YAML loading that remembers where each key came from, so errors can name file and line.

Also the dissertation's array layout (`size` + `sensor0`, `sensor1`, …), shared by the agent's
parameter files and the config toolchain.
"""

from __future__ import annotations

import difflib
import math
from pathlib import Path
from typing import Any

import msgspec
import yaml
from yaml.composer import Composer
from yaml.constructor import SafeConstructor
from yaml.cyaml import CParser
from yaml.resolver import Resolver

from .codec import validation_fault
from .errors import ConfigError


class YamlDoc:
    def __init__(self, path: Path, data: Any, lines: dict[tuple, int]):
        self.path = path
        self.data = data
        self.lines = lines

    def line(self, path: tuple) -> int | None:
        while path:
            if path in self.lines:
                return self.lines[path]
            path = path[:-1]
        return None

    def error(self, path: tuple, message: str) -> ConfigError:
        key = "/".join(map(str, path)) or "(top level)"
        return ConfigError(message, file=str(self.path), line=self.line(path), element=f"'{key}'")

    def convert(self, path: tuple, kind: type) -> Any:
        """The mapping at `path` as the msgspec Struct `kind` (absent: all defaults), checked:
        a wrong type, an unknown key or a non-finite number is a ConfigError naming the key."""
        data = get_path(self.data, path)
        if data is None:
            data = {}
        if not isinstance(data, dict):
            raise self.error(path, f"expected a mapping of parameters, got {type(data).__name__}")
        try:
            return msgspec.convert(data, kind, strict=True)
        except msgspec.ValidationError as exc:
            fault = validation_fault(exc)
            where = path + fault.path
            if fault.unknown:
                key = fault.unknown
                fields = getattr(kind, "__struct_fields__", ())
                raise self.error(where + (key,), f"unknown key {key!r}"
                                 + did_you_mean(key, fields)) from None
            value = get_path(self.data, where) if not fault.in_key else None
            non_finite = isinstance(value, float) and not math.isfinite(value)
            what = "expected a finite number" if fault.not_finite or non_finite \
                else fault.what.replace("`", "")
            raise self.error(where, f"a key: {what}" if fault.in_key else what) from None

    def warning(self, path: tuple, message: str) -> str:
        """The same `file:line: 'key': message` text as error(), for legal but suspicious values."""
        return str(self.error(path, message))


# A parameter, world or experiment file is data: text, numbers, booleans, lists and mappings
# whose keys are text. Anything else YAML can say is refused with its line, because what it
# builds reaches code that expects JSON-like data (a date key, `? [a, b]`, !!binary, !!set) and
# would fail there with a traceback instead of naming the file.
MAX_BYTES = 8 * 1024 * 1024  # the largest file read (a parameter file is a few kB)
_TAG = "tag:yaml.org,2002:"
_KIND = {"int": "a number", "float": "a number", "bool": "a boolean", "null": "null",
         "timestamp": "a date"}
_REFUSED_TAGS = ("binary", "timestamp", "omap", "pairs", "set")


class _StrictLoader(Composer, CParser, SafeConstructor, Resolver):
    """SafeLoader that refuses duplicate keys (YAML's "last one wins" silently loses a value),
    keys that are not text, integers too long to convert, dates, binary data, sets and ordered
    maps — each with its line — and, for parameter files, anchors and aliases (a "billion
    laughs" file would otherwise expand without bound wherever the data is walked).

    libyaml (CParser) scans and parses: a robot of a 100-task delivery run reads ≈ 60 kB of
    parameters at start-up, 0.4 CPU s in PyYAML's Python scanner, 0.09 s so. Composing stays
    PyYAML's (Composer first in the bases), so compose_node below still sees every anchor and
    alias before a node is built."""

    allow_aliases = False

    def __init__(self, stream: str):
        CParser.__init__(self, stream)
        Composer.__init__(self)
        SafeConstructor.__init__(self)
        Resolver.__init__(self)

    def compose_node(self, parent, index):
        if self.allow_aliases:
            return super().compose_node(parent, index)
        if self.check_event(yaml.AliasEvent):
            event = self.peek_event()
            raise yaml.composer.ComposerError(
                None, None, "YAML aliases (*name) are not allowed in parameter files",
                event.start_mark)
        event = self.peek_event()
        if getattr(event, "anchor", None):
            raise yaml.composer.ComposerError(
                None, None, "YAML anchors (&name) are not allowed in parameter files",
                event.start_mark)
        return super().compose_node(parent, index)

    def construct_mapping(self, node, deep=False):
        seen: dict = {}
        for key_node, _ in node.value:
            _check_key(key_node)
            if key_node.tag == _TAG + "merge":
                continue
            key = key_node.value
            if key in seen:
                raise yaml.constructor.ConstructorError(
                    None, None, f"duplicate key {key!r} (first on line {seen[key]})",
                    key_node.start_mark)
            seen[key] = key_node.start_mark.line + 1
        self.flatten_mapping(node)  # `<<:` brings keys in: they must be text too
        for key_node, _ in node.value:
            _check_key(key_node)
        return super().construct_mapping(node, deep)

    def construct_yaml_int(self, node):
        try:
            return super().construct_yaml_int(node)
        except ValueError:  # past Python's 4,300 digits (int_max_str_digits)
            raise yaml.constructor.ConstructorError(
                None, None, f"an integer of {len(node.value):,} characters is too long",
                node.start_mark) from None

    def construct_refused(self, node):
        kind = node.tag[len(_TAG):] if node.tag.startswith(_TAG) else node.tag
        hint = " (quote it if it is text)" if kind == "timestamp" else ""
        raise yaml.constructor.ConstructorError(
            None, None, f"{_KIND.get(kind, '!!' + kind)} is not allowed here{hint}: "
            "only text, numbers, booleans, lists and mappings", node.start_mark)


def _check_key(key_node: yaml.Node) -> None:
    """A mapping key must be text: `? [a, b]` (a list as key) and `2020-01-01:` (a date) would
    otherwise reach the code as keys it cannot hash or compare with its own."""
    if not isinstance(key_node, yaml.ScalarNode):
        what = "a list" if isinstance(key_node, yaml.SequenceNode) else "a mapping"
        raise yaml.constructor.ConstructorError(
            None, None, f"a key must be text, not {what} (YAML complex key)",
            key_node.start_mark)
    if key_node.tag == _TAG + "merge":
        return  # `<<:` merges the mapping it names into this one (flatten_mapping)
    if key_node.tag != _TAG + "str":
        kind = key_node.tag[len(_TAG):] if key_node.tag.startswith(_TAG) else key_node.tag
        raise yaml.constructor.ConstructorError(
            None, None, f"key {key_node.value[:40]!r} is read as "
            f"{_KIND.get(kind, '!!' + kind)}; keys must be text: quote it",
            key_node.start_mark)


_StrictLoader.add_constructor(_TAG + "map", _StrictLoader.construct_mapping)
_StrictLoader.add_constructor(_TAG + "int", _StrictLoader.construct_yaml_int)
for _tag in _REFUSED_TAGS:
    _StrictLoader.add_constructor(_TAG + _tag, _StrictLoader.construct_refused)


class _AliasLoader(_StrictLoader):
    allow_aliases = True


def read_bounded(path: Path, what: str) -> bytes:
    """The bytes of `path`, read no further than MAX_BYTES: a larger file (a log or an image
    given by mistake) is a ConfigError naming the file, not a reader stuck on it."""
    try:
        with path.open("rb") as f:
            raw = f.read(MAX_BYTES + 1)
    except OSError as exc:
        raise ConfigError(f"cannot read: {exc.strerror}", file=str(path)) from None
    if len(raw) > MAX_BYTES:
        raise ConfigError(f"larger than {MAX_BYTES // (1024 * 1024)} MiB: not {what}",
                          file=str(path))
    return raw


def load_yaml(path: Path | str, aliases: bool = False) -> YamlDoc:
    """A YAML file with line numbers per key; ConfigError (file, line) for anything malformed —
    duplicate or non-text keys, characters YAML forbids (NUL), integers too long, dates, tags
    beyond plain data — and aliases unless `aliases` (answers files use them to share a block;
    each node is then walked once)."""
    path = Path(path)
    raw = read_bounded(path, "a parameter file")
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise ConfigError("not a UTF-8 text file", file=str(path),
                          line=raw.count(b"\n", 0, exc.start) + 1) from None
    return parse_yaml(text, path, aliases)


def parse_yaml(text: str, path: Path | str, aliases: bool = False) -> YamlDoc:
    """load_yaml's, from text already read (what a generator is about to write): `path` is
    what errors name."""
    path = Path(path)
    try:
        loader = (_AliasLoader if aliases else _StrictLoader)(text)
        try:
            node = loader.get_single_node()
            data = loader.construct_document(node) if node is not None else {}
        finally:
            loader.dispose()
        lines: dict[tuple, int] = {}
        if node is not None:
            _walk(node, (), lines, set())
    except yaml.reader.ReaderError as exc:  # a character YAML forbids: it gives no line
        name = "NUL" if exc.character == 0 else f"#x{exc.character:04x}"
        raise ConfigError(f"invalid YAML: character {name} is not allowed",
                          file=str(path), line=text.count("\n", 0, exc.position) + 1) from None
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        problem = getattr(exc, "problem", None) or str(exc)
        raise ConfigError(f"invalid YAML: {' '.join(problem.split())}", file=str(path),
                          line=mark.line + 1 if mark else None) from None
    except RecursionError:
        raise ConfigError("invalid YAML: nested too deeply", file=str(path)) from None
    return YamlDoc(path, data if data is not None else {}, lines)


def _walk(node: yaml.Node, path: tuple, lines: dict, seen: set) -> None:
    lines[path] = node.start_mark.line + 1
    if id(node) in seen:  # an aliased node: its lines were recorded where it was defined
        return
    seen.add(id(node))
    if isinstance(node, yaml.MappingNode):
        for k, v in node.value:
            key = k.value
            _walk(v, path + (key,), lines, seen)
            lines[path + (key,)] = k.start_mark.line + 1  # the key's line, not its value's
    elif isinstance(node, yaml.SequenceNode):
        for i, v in enumerate(node.value):
            _walk(v, path + (i,), lines, seen)


def plural(n: int, word: str, many: str | None = None) -> str:
    """`1 robot`, `2 robots`: counts in messages read as English (library and CLI alike)."""
    return f"{n} {word if n == 1 else (many or word + 's')}"


def did_you_mean(word: str, options) -> str:
    close = difflib.get_close_matches(str(word), [str(o) for o in options], n=1, cutoff=0.6)
    return f" (did you mean {close[0]!r}?)" if close else ""


def sized_array(doc: YamlDoc, path: tuple, item_prefix: str) -> list[tuple[tuple, dict]]:
    """Items of a `size` + `<prefix>0…` block as (path, mapping) pairs, checked for consistency."""
    block = get_path(doc.data, path)
    if block is None:
        raise doc.error(path, f"missing mandatory key {path[-1]!r}")
    if not isinstance(block, dict):
        raise doc.error(path, "expected a mapping with 'size' and "
                              f"'{item_prefix}0', '{item_prefix}1', …")
    size = block.get("size")
    if type(size) is not int or size < 0:
        raise doc.error(path + ("size",), f"'size' must be a non-negative integer, got {size!r}")
    items = []
    for i in range(size):
        name = f"{item_prefix}{i}"
        item = block.get(name)
        if not isinstance(item, dict):
            raise doc.error(path, f"size is {size} but '{name}' is missing or not a mapping")
        items.append((path + (name,), item))
    allowed = {"size"} | {f"{item_prefix}{i}" for i in range(size)}
    for key in block:
        if key not in allowed:
            raise doc.error(path + (key,), f"unexpected key {key!r} (size is {size})"
                            + did_you_mean(key, allowed))
    return items


def get_path(data: Any, path: tuple) -> Any:
    """The value at `path` in nested mappings, or None where a key is missing or not a mapping."""
    for p in path:
        if not isinstance(data, dict):
            return None
        data = data.get(p)
    return data
