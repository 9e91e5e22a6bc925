"""JSON Schemas that Foxglove's and Lichtblick's parsers take (their `parseJsonSchema`).

Those parsers read a schema in one pass, without a JSON Schema library: the root and every
nested object must say `"type": "object"` and have `properties`; a property's `type` must be
one string of boolean, string, number, integer, object or array (`"null"`, a list of types,
`$ref`, `anyOf`/`oneOf` are refused, and one refused property blanks the whole channel); an
array's `items` must have such a type too, and an array of arrays or of base64 strings is
refused. msgspec writes `$ref`/`$defs`, `anyOf` for optional fields and a bare `enum` for
literals — each of them makes the apps refuse the channel — so every schema a recording or a
live channel carries goes through `flatten` first.

What flattening gives up, on purpose:
* nullable values: a field `X | None` is declared as X and left out of `required` (the parsers
  have no way to say "or null"; a null value is shown as empty). The viewers' own channels
  (supervisor/live/foxglove.py) drop null values from their messages instead, so their messages
  also validate against their schemas;
* enums and constants: declared as their values' type (the panels show the value);
* shapes the parsers cannot describe (a tuple of mixed types, an array of arrays, a recursive
  type): the property is left out of the schema — its values are still in every message, so a
  Raw Messages panel shows them — and named in the schema's description.
"""

from __future__ import annotations

import functools
import json
import math
from typing import Any

import msgspec

from . import codec

__all__ = ["flatten", "from_viewer", "message_schema", "object_schema", "to_viewer"]

_json = msgspec.json  # lossless for our values: shortest round-trip floats
SCALARS = ("boolean", "string", "number", "integer")
STAMP_SECONDS = "stamp_seconds"  # the header stamp's exact float, beside its {sec, nsec} form
TIME = {"type": "object", "title": "time",
        "description": "the header stamp as ROS time: whole seconds and nanoseconds",
        "properties": {"sec": {"type": "integer"}, "nsec": {"type": "integer"}},
        "required": ["sec", "nsec"]}
MAX_DEPTH = 32  # nested objects followed; deeper (a recursive type) is left out


class _Unsupported(Exception):
    """A shape the viewers' parsers cannot read."""


def object_schema(title: str, description: str = "") -> dict:
    """The schema of a type nothing more is known of: an object with no declared fields (the
    parsers need `properties`, even empty)."""
    out: dict[str, Any] = {"title": title, "type": "object", "properties": {}}
    if description:
        out["description"] = description
    return out


def has_header(cls: type) -> bool:
    """Whether a message class has our Header as its `header` field."""
    from .messages import Header
    return any(f.name == "header" and f.type is Header for f in msgspec.structs.fields(cls))


@functools.cache
def message_schema(cls: type) -> bytes:
    """A message class's flattened schema, as the bytes a channel carries (cached: the same
    class is asked for once per channel).

    msgspec builds the class's type information to write its schema (a Decoder of it), and two
    threads building one type's at once crash the process: a recorder's writer thread asking
    for a channel's schema while Zenoh's threads decode the same types' first samples killed
    `mrta record` with SIGSEGV (tests/process/test_recorder_crash.py). So the class's decoder is built
    first, the codec's way, and the schema under the codec's lock."""
    codec.struct_decoder(cls)
    with codec.TYPE_INFO_LOCK:
        schema = msgspec.json.schema(cls)
    out = flatten(schema)
    if has_header(cls):
        header = out["properties"]["header"]
        header["properties"]["stamp"] = TIME
        header["properties"][STAMP_SECONDS] = {
            "type": "number", "description": "the stamp in seconds, as the sender wrote it"}
        header["required"] = [*header.get("required", ()), STAMP_SECONDS]
    return json.dumps(out).encode()


# ------------------------------------------------------------------ header stamps
# Foxglove's and Lichtblick's panels read `header.stamp` of every message as ROS time: the Plot
# panel evaluates `"sec" in header.stamp` for each message it plots, which throws on a number —
# our stamp is seconds as a float (the wire format) — and the panel shows an error instead of
# its lines. So the JSON that viewers get (recordings, live channels) writes a top-level
# header's stamp as {sec, nsec}, and keeps the exact float beside it (`stamp_seconds`), from
# which `from_viewer` gives the wire's message back bit for bit (sec + nsec / 1e9 would not).

class _Time(msgspec.Struct, gc=False):
    sec: int
    nsec: int


class _ViewerHeader(msgspec.Struct, gc=False):
    frame_id: str
    stamp: _Time
    seq: int
    stamp_seconds: float


def to_viewer(cls: type):
    """message → the JSON bytes viewers get (the header stamp as above)."""
    if not has_header(cls):
        return _json.encode
    replace, encode, floor = msgspec.structs.replace, _json.encode, math.floor

    def to_json(message) -> bytes:
        h = message.header
        sec = floor(h.stamp)
        nsec = min(round((h.stamp - sec) * 1e9), 999_999_999)
        return encode(replace(message, header=_ViewerHeader(h.frame_id, _Time(sec, nsec), h.seq,
                                                            h.stamp)))

    return to_json


def from_viewer(data: bytes, cls: type):
    """The message of a viewer's JSON (to_viewer's, or a plain one) — msgspec's errors raised."""
    try:
        return _json.decode(data, type=cls)
    except msgspec.ValidationError:
        value = _json.decode(data)
        header = value.get("header") if isinstance(value, dict) else None
        if not (isinstance(header, dict) and isinstance(header.get("stamp"), dict)
                and STAMP_SECONDS in header):
            raise
        header["stamp"] = header.pop(STAMP_SECONDS)
        return _json.decode(_json.encode(value), type=cls)


def flatten(schema: dict) -> dict:
    """A self-contained schema with `"type": "object"` at its root, no `$ref`/`$defs`, one
    type string per property and typed array items (module docstring)."""
    defs = schema.get("$defs", {})
    root = _resolve(schema, defs)
    if _type_of(root, defs) != "object":
        raise ValueError(f"not an object schema: {json.dumps(schema)[:200]}")
    return _object(root, defs, 0)


def _resolve(node: dict, defs: dict) -> dict:
    seen = 0
    while "$ref" in node:
        ref = node["$ref"]
        if not ref.startswith("#/$defs/") or seen > MAX_DEPTH:
            raise _Unsupported(f"reference {ref}")
        extra = {k: v for k, v in node.items() if k != "$ref"}
        node = {**defs[ref.removeprefix("#/$defs/")], **extra}
        seen += 1
    return node


def _alternatives(node: dict) -> list[dict] | None:
    for key in ("anyOf", "oneOf"):
        if key in node:
            return node[key]
    return None


def _type_of(node: dict, defs: dict) -> str:
    """The one type a (resolved) node describes, null alternatives set aside."""
    alts = _alternatives(node)
    if alts is not None:
        types = {_type_of(_resolve(a, defs), defs) for a in alts} - {"null"}
        if types <= {"integer", "number"} and types:
            return "number" if "number" in types else "integer"
        if len(types) != 1:
            raise _Unsupported(f"one of {sorted(types)}")
        return types.pop()
    t = node.get("type")
    if isinstance(t, list):
        types = set(t) - {"null"}
        if types <= {"integer", "number"} and types:
            return "number" if "number" in types else "integer"
        if len(types) != 1:
            raise _Unsupported(f"one of {sorted(types)}")
        return types.pop()
    if t is not None:
        return t
    values = node.get("enum", [node["const"]] if "const" in node else None)
    if values:
        kinds = {_json_type(v) for v in values}
        if kinds <= {"integer", "number"}:
            return "number" if "number" in kinds else "integer"
        if len(kinds) == 1:
            return kinds.pop()
    raise _Unsupported("no type")


def _json_type(value: Any) -> str:
    if isinstance(value, bool):
        return "boolean"
    if isinstance(value, int):
        return "integer"
    if isinstance(value, float):
        return "number"
    if isinstance(value, str):
        return "string"
    return "unsupported"


def _non_null(node: dict, defs: dict) -> dict:
    """The non-null alternative of an optional node (itself for any other node)."""
    alts = _alternatives(node)
    if alts is None:
        return node
    rest = [_resolve(a, defs) for a in alts if _resolve(a, defs).get("type") != "null"]
    return rest[0] if len(rest) == 1 else node


def _nullable(node: dict, defs: dict) -> bool:
    alts = _alternatives(node)
    if alts is not None:
        return any(_resolve(a, defs).get("type") == "null" for a in alts)
    t = node.get("type")
    return isinstance(t, list) and "null" in t


def _field(node: dict, defs: dict, depth: int) -> dict:
    """One property (or array item) in the parsers' terms; _Unsupported if it has none."""
    node = _resolve(node, defs)
    t = _type_of(node, defs)
    inner = _non_null(node, defs)
    keep = {k: inner[k] for k in ("title", "description") if k in inner}
    if "description" in node:
        keep["description"] = node["description"]
    if t == "object":
        return {**keep, **_object(inner, defs, depth + 1)}
    if t == "array":
        items = _array_items(inner, defs)
        item = _field(items, defs, depth)
        if item["type"] == "array" or "contentEncoding" in item:
            raise _Unsupported("an array of arrays or of encoded strings")
        return {**keep, "type": "array", "items": item}
    if t not in SCALARS:
        raise _Unsupported(f"type {t}")
    out = {**keep, "type": t}
    encoding = inner.get("contentEncoding")
    if encoding is not None:
        if t != "string" or encoding != "base64":
            raise _Unsupported(f"contentEncoding {encoding}")
        out["contentEncoding"] = "base64"
    return out


def _array_items(node: dict, defs: dict) -> dict:
    if "items" in node and isinstance(node["items"], dict):
        return node["items"]
    prefix = node.get("prefixItems")
    if prefix:  # a tuple: readable when all its members have one type
        types = {_type_of(_resolve(p, defs), defs) for p in prefix}
        if len(types) == 1 and types <= set(SCALARS):
            return {"type": types.pop()}
    raise _Unsupported("an array without one item type")


def _object(node: dict, defs: dict, depth: int) -> dict:
    if depth > MAX_DEPTH:
        raise _Unsupported("nested too deep (a recursive type)")
    props: dict[str, dict] = {}
    left_out: list[str] = []
    required = set(node.get("required", ()))
    for name, sub in node.get("properties", {}).items():
        try:
            props[name] = _field(sub, defs, depth)
        except _Unsupported as exc:
            left_out.append(f"{name} ({exc})")
            continue
        if _nullable(_resolve(sub, defs), defs):
            required.discard(name)
    out: dict[str, Any] = {k: node[k] for k in ("title", "description") if k in node}
    out["type"] = "object"
    out["properties"] = props
    req = [n for n in node.get("required", ()) if n in required and n in props]
    if req:
        out["required"] = req
    extra = node.get("additionalProperties")
    if isinstance(extra, dict):  # a mapping: its values' type, when the parsers can read it
        try:
            out["additionalProperties"] = _field(extra, defs, depth)
        except _Unsupported:
            pass
    elif extra is False:
        out["additionalProperties"] = False
    if left_out:
        note = "Not described here (the viewers' parsers cannot read them): " \
            + ", ".join(left_out) + "."
        out["description"] = (out.get("description", "") + "\n\n" + note).strip()
    return out
