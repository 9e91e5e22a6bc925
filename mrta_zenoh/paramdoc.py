"""Parameter files read as typed documents: a YAML mapping converted to a msgspec Struct, with
the errors a person can act on — file, line, key, and a "did you mean" for a misspelt key.

One idiom for every parameter file an architecture reads (its robot, tasks and dispatcher
files), as the experiment file and the plugins' sections already are: the Struct is the key
set (no list of allowed keys kept beside a dataclass), its annotations carry the bounds.
Reading is three steps:

1. **Sized arrays to lists.** rqt_mrta writes arrays as a mapping with `size` and `<item>0`,
   `<item>1`, … (`sensors: {size: 2, sensor0: …, sensor1: …}`). A field declared
   `sized(Item, "sensor")` is read from that layout: one pre-pass, driven by the Struct, checks
   each block (`size` a whole number, every item present, no stray key) and turns it into a
   list, remembering where each item came from, so later errors still name `sensors/sensor1`.
2. **Shape.** msgspec converts the data (strict: no "2" for 2): a missing, unknown or mistyped
   key becomes a ConfigError naming the file's key path and line.
3. **Values.** Every float must be finite; a field annotated with a `Check` (`Rate`,
   `Duration`, `Positive`, `Text`, `Id`, `whole(…)`, `within(…)`) must pass it — the ranges are
   mrta_zenoh.limits', so `mrta arch validate` refuses what the runtime would.

What crosses fields (a lease longer than a tick, a sensor topic the robot has) stays with the
architecture, which raises through `Document.error` with the document's own paths.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Annotated, Any, Callable, Generic, TypeVar

import msgspec
import msgspec.inspect as mi

from .codec import validation_fault
from .keys import is_id
from .limits import DURATION, RATE, Range
from .yamlfile import YamlDoc, did_you_mean, load_yaml, sized_array

T = TypeVar("T")
CHECK, SIZED = "mrta.check", "mrta.sized"


@dataclass(frozen=True)
class Check:
    """A value's bound: `expected` completes "KEY …, got VALUE" when the type is wrong,
    `problem(value)` says what is wrong with a value of the right type (None: fine)."""

    expected: str
    problem: Callable[[Any], str | None]  # follows the key's name: "spin_rate must be > 0"


def _number(positive: bool = False, range_: Range | None = None) -> Check:
    def problem(value: float) -> str | None:
        if positive and value <= 0:
            return f"must be > 0, got {value:g}"
        return range_.problem(value) if range_ is not None else None
    return Check("must be a number", problem)


def checked(kind: Any, check: Check) -> Any:
    """`kind` with `check` applied after conversion."""
    return Annotated[kind, msgspec.Meta(extra={CHECK: check})]


def within(range_: Range, positive: bool = False) -> Any:
    """A number inside `range_` (and > 0 first, with `positive`: the error says so)."""
    return checked(float, _number(positive, range_))


def whole(low: int, high: int | None = None) -> Any:
    """A whole number ≥ low (≤ high when given)."""
    text = f"a whole number in [{low}, {high}]" if high is not None else f"a whole number ≥ {low}"

    def problem(value: int) -> str | None:
        bad = value < low or (high is not None and value > high)
        return f"must be {text}, got {value}" if bad else None
    return checked(int, Check(f"must be {text}", problem))


def sized(item: Any, prefix: str) -> Any:
    """A list written in rqt_mrta's sized layout: `size` and `<prefix>0`, `<prefix>1`, …"""
    return Annotated[list[item], msgspec.Meta(extra={SIZED: prefix})]


def _text(value: str) -> str | None:
    return None if value.strip() else f"must be a non-empty string, got {value!r:.40}"


def _id(value: str) -> str | None:
    if is_id(value):
        return None
    return _text(value) or (f"{value!r:.80} must be one key chunk: up to 64 letters, digits, "
                            "'_', '-' or '.'")


Rate = within(RATE, positive=True)           # Hz: positive, finite, what a process can honour
Duration = within(DURATION, positive=True)   # s: positive, finite, at most a day
Positive = checked(float, _number(positive=True))
NonNegative = checked(float, Check("must be a number",
                                   lambda v: f"must be ≥ 0, got {v:g}" if v < 0 else None))
Text = checked(str, Check("must be a non-empty string", _text))
Id = checked(str, Check("must be a non-empty string", _id))  # a task id: one key chunk


@dataclass
class Document(Generic[T]):
    """A converted document, and the way back from its paths (list indices) to the file's
    (`sensor1`), for errors and warnings found after conversion."""

    doc: YamlDoc
    value: T
    base: tuple = ()                                     # where the Struct sits in the file
    sized: dict[tuple, str] = field(default_factory=dict)  # a list's path → its item prefix

    def origin(self, path: tuple) -> tuple:
        """The file's key path of `path` (a path in `value`)."""
        out = list(self.base)
        for i, step in enumerate(path):
            prefix = self.sized.get(tuple(path[:i]))
            out.append(f"{prefix}{step}" if prefix is not None and isinstance(step, int)
                       else step)
        return tuple(out)

    def error(self, path: tuple, message: str):
        return self.doc.error(self.origin(path), message)

    def warning(self, path: tuple, message: str) -> str:
        return self.doc.warning(self.origin(path), message)

    def where(self, path: tuple) -> str:
        """`file:line` of the key at `path`, for errors raised once the plugins load."""
        line = self.doc.line(self.origin(path))
        return f"{self.doc.path}:{line}" if line else str(self.doc.path)


def load(path: Path | str, kind: type[T], what: str) -> Document[T]:
    """The YAML file at `path` as the Struct `kind`; `what` names the file when its top level
    is not a mapping ("a tasks parameter file")."""
    doc = load_yaml(path)
    if not isinstance(doc.data, dict):
        raise doc.error((), f"{what} must be a mapping")
    return read(doc, kind)


def read(doc: YamlDoc, kind: type[T], base: tuple = ()) -> Document[T]:
    """The mapping at `base` of `doc` as the Struct `kind` (sized arrays, shape, values)."""
    info = mi.type_info(kind)
    out: Document[T] = Document(doc, None, base)  # type: ignore[arg-type]
    data = doc.data
    for step in base:
        data = data.get(step) if isinstance(data, dict) else None
    if not isinstance(data, dict):
        raise doc.error(base, "expected a mapping")
    data = _unsized(out, info, data, ())
    try:
        out.value = msgspec.convert(data, kind, strict=True)
    except msgspec.ValidationError as exc:
        raise _shape_error(out, info, data, exc) from None
    _check(out, info, out.value, data, ())
    return out


# ----------------------------------------------------------------------------- the three steps

def _bare(t: mi.Type) -> tuple[mi.Type, Check | None, str | None]:
    """A type without its metadata, with the metadata's check and sized prefix."""
    check = prefix = None
    while isinstance(t, mi.Metadata):
        extra = t.extra or {}
        check, prefix = extra.get(CHECK, check), extra.get(SIZED, prefix)
        t = t.type
    return t, check, prefix


def _check_of(t: mi.Type) -> Check | None:
    """The check of `t`, or of the one type an optional `t` is when not null."""
    bare, check, _ = _bare(t)
    if check is None and isinstance(bare, mi.UnionType):
        members = [m for m in bare.types if not isinstance(m, mi.NoneType)]
        return _bare(members[0])[1] if len(members) == 1 else None
    return check


def _struct_of(t: mi.Type) -> mi.StructType | None:
    t = _bare(t)[0]
    if isinstance(t, mi.UnionType):
        return next((s for s in map(_struct_of, t.types) if s is not None), None)
    return t if isinstance(t, mi.StructType) else None


def _unsized(out: Document, t: mi.Type, data: Any, path: tuple) -> Any:
    """`data` with every sized block of `t` turned into a list (step 1)."""
    struct = _struct_of(t)
    if struct is not None and isinstance(data, dict):
        data = dict(data)
        for f in struct.fields:
            if f.encode_name not in data:
                continue
            key = f.encode_name
            ft, _, prefix = _bare(f.type)
            if prefix is not None:
                items = sized_array(out.doc, out.origin(path + (key,)), prefix)
                out.sized[path + (key,)] = prefix
                data[key] = [_unsized(out, ft.item_type, item, path + (key, i))
                             for i, (_, item) in enumerate(items)]
            else:
                data[key] = _unsized(out, f.type, data[key], path + (key,))
        return data
    ft = _bare(t)[0]
    if isinstance(ft, (mi.ListType, mi.VarTupleType)) and isinstance(data, list):
        return [_unsized(out, ft.item_type, item, path + (i,)) for i, item in enumerate(data)]
    return data


def _type_at(t: mi.Type, path: tuple) -> mi.Type | None:
    """The declared type of the value at `path` (None where the path leaves the type)."""
    for step in path:
        if isinstance(step, int):
            inner = _bare(t)[0]
            if not isinstance(inner, (mi.ListType, mi.VarTupleType)):
                return None
            t = inner.item_type
        else:
            struct = _struct_of(t)
            f = next((f for f in struct.fields if f.encode_name == step), None) if struct else None
            if f is None:
                return None
            t = f.type
    return t


def _value_at(data: Any, path: tuple) -> Any:
    for step in path:
        if isinstance(step, int) and isinstance(data, list) and step < len(data):
            data = data[step]
        elif isinstance(data, dict):
            data = data.get(step)
        else:
            return None
    return data


_EXPECTED = {"float": "must be a number", "int | float": "must be a number",
             "str": "must be a non-empty string", "int": "must be a whole number",
             "bool": "must be true or false", "array": "must be a list"}


def _shape_error(out: Document, info: mi.Type, data: Any, exc: msgspec.ValidationError):
    """msgspec's complaint about the shape (step 2) as a ConfigError naming the file's key."""
    fault = validation_fault(exc)
    path = tuple(fault.path)
    if fault.missing:
        return out.error(path + (fault.missing,), f"missing mandatory key {fault.missing!r}")
    if fault.unknown:
        struct = _struct_of(_type_at(info, path)) if _type_at(info, path) else None
        fields = [f.encode_name for f in struct.fields] if struct else []
        return out.error(path + (fault.unknown,),
                         f"unknown key {fault.unknown!r}" + did_you_mean(fault.unknown, fields))
    if fault.in_key:
        return out.error(path, f"a key: {fault.what.replace('`', '')}")
    key = next((s for s in reversed(path) if isinstance(s, str)), "value")
    value = _value_at(data, path)
    expected = fault.expected.removesuffix(" | null")  # an optional value: null is fine too
    if expected == "object":
        return out.error(path, f"expected a mapping, got {type(value).__name__}")
    declared = _type_at(info, path)
    enum = _bare(declared)[0] if declared is not None else None
    if isinstance(enum, mi.EnumType) and fault.what.startswith("Invalid enum value"):
        known = [m.value for m in enum.cls]
        return out.error(path, f"{key} {value!r:.40} is not one of "
                         f"{', '.join(map(str, known))}" + did_you_mean(value, known))
    check = _check_of(declared) if declared is not None else None
    expected = check.expected if check is not None else _EXPECTED.get(expected)
    if expected is None:
        return out.error(path, fault.what.replace("`", ""))
    return out.error(path, f"{key} {expected}, got {value!r:.40}")


def _check(out: Document, t: mi.Type, value: Any, raw: Any, path: tuple) -> None:
    """Every float finite, every Check passed (step 3), in the Struct's field order; a default
    (a key the file leaves out: `raw` lacks it) is the Struct's word, not checked."""
    if value is None:
        return
    bare, check = _bare(t)[0], _check_of(t)
    key = next((s for s in reversed(path) if isinstance(s, str)), "value")
    if isinstance(value, float) and not math.isfinite(value):
        raise out.error(path, f"{key} must be a finite number, got {value}")
    if check is not None:
        problem = check.problem(value)
        if problem is not None:
            raise out.error(path, f"{key} {problem}")
    struct = _struct_of(bare)
    if struct is not None and isinstance(value, msgspec.Struct):
        for f in struct.fields:
            if isinstance(raw, dict) and f.encode_name in raw:
                _check(out, f.type, getattr(value, f.name), raw[f.encode_name],
                       path + (f.encode_name,))
    elif isinstance(bare, (mi.ListType, mi.VarTupleType)):
        for i, item in enumerate(value):
            _check(out, bare.item_type, item, raw[i], path + (i,))
    elif isinstance(bare, mi.DictType):
        for k, item in value.items():
            _check(out, bare.value_type, item, raw[k], path + (k,))
