"""Every JSON Schema a recording or a live channel carries is one Foxglove Studio's and
Lichtblick's parsers take. Both apps read a channel's JSON Schema with their own
`parseJsonSchema` (packages/mcap-support in foxglove/studio and in lichtblick-suite/lichtblick),
not with a JSON Schema library; `lint` below restates its rules, where the two differ the
stricter one (Lichtblick has no `oneOf` enums), independently of mrta_zenoh.flat_schema:

* the root, and every nested object, has `"type": "object"` (`$ref`/`$defs` give none) and
  `properties` (it iterates them; an absent one throws);
* a property's `type` is one of boolean, string, number, integer, object, array — a list of
  types or "null" is refused ("Unsupported type");
* a string's `contentEncoding` is absent or base64;
* an array's `items` has a type of boolean, string (no contentEncoding), number, integer,
  object — no array of arrays.

One refused property and the app refuses the whole channel (the Problems tab, empty plots)."""

from __future__ import annotations

import json
from importlib.metadata import entry_points

import jsonschema
import msgspec
import pytest

from mrta_zenoh import codec
from mrta_zenoh.flat_schema import flatten, object_schema
from mrta_zenoh.messages import message_class
from mrta_zenoh.recording import LIVELINESS_SCHEMA, json_channel
from mrta_supervisor.live.foxglove import ROBOT_TASK_SCHEMA, SUPERVISOR_SNAPSHOT_SCHEMA

SCALAR = {"boolean", "string", "number", "integer"}


def lint(schema: dict, name: str = "root") -> list[str]:
    """What the apps' parser says of `schema` (an empty list: it takes it)."""
    problems: list[str] = []

    def obj(node, path):
        if not isinstance(node, dict) or node.get("type") != "object":
            problems.append(f'{path}: Expected "type": "object", got '
                            f"{json.dumps(node.get('type') if isinstance(node, dict) else node)}")
            return
        props = node.get("properties")
        if not isinstance(props, dict):
            problems.append(f"{path}: no properties")
            return
        for field, sub in props.items():
            prop(sub, f"{path}.{field}")

    def prop(node, path):
        t = node.get("type") if isinstance(node, dict) else None
        t = t if isinstance(t, str) else json.dumps(t)  # a list of types: refused
        if t == "object":
            obj(node, path)
        elif t == "string":
            if node.get("contentEncoding") not in (None, "base64"):
                problems.append(f"{path}: contentEncoding {node['contentEncoding']}")
        elif t == "array":
            items = node.get("items")
            it = items.get("type") if isinstance(items, dict) else None
            it = it if isinstance(it, str) else json.dumps(it)
            if it == "object":
                obj(items, f"{path}[]")
            elif it not in SCALAR:
                problems.append(f"{path}: Unsupported array item type {it}")
            elif it == "string" and "contentEncoding" in items:
                problems.append(f"{path}: contentEncoding for array item")
        elif t not in SCALAR:
            problems.append(f"{path}: Unsupported type {t}")

    obj(schema, name)
    return problems


def registered_types() -> list[str]:
    return sorted({ep.name for ep in entry_points(group="mrta.messages")})


def test_the_lint_refuses_what_the_apps_refused():
    """msgspec's own output (`$ref` at the root), a nullable number, a bare enum, an object
    without properties, an array of arrays: each as the apps' parser refused it."""
    motivation = msgspec.json.schema(message_class("alliance_msgs/Motivation"))
    assert lint(motivation) == ['root: Expected "type": "object", got null']
    assert lint({"type": "object", "properties": {"t": {"type": ["number", "null"]}}})
    assert lint({"type": "object", "properties": {"e": {"enum": ["a", "b"]}}})
    assert lint({"type": "object"}) == ["root: no properties"]
    assert lint({"type": "object", "properties": {"a": {"type": "array", "items": {
        "type": "array", "items": {"type": "number"}}}}})
    assert lint({"type": "object", "properties": {"a": {"type": "array"}}})
    assert lint({"type": "object", "properties": {"n": {"type": "null"}}})


@pytest.mark.parametrize("type_name", registered_types())
def test_every_registered_message_types_channel_schema_is_one_the_apps_take(type_name):
    (name, encoding, data), _ = json_channel(codec.encoding_for(type_name))
    schema = json.loads(data)
    assert (name, encoding) == (type_name, "jsonschema")
    assert lint(schema, type_name) == []
    assert "$ref" not in data.decode() and "$defs" not in data.decode()
    jsonschema.Draft202012Validator.check_schema(schema)
    # the same fields as the message definition, at the top level: each one described, or
    # named in the description as a shape the parsers cannot read (flat_schema's rule)
    fields = set(message_class(type_name).__struct_fields__)
    left_out = fields - set(schema["properties"])
    assert set(schema["properties"]) <= fields
    note = schema.get("description", "").partition("Not described here")[2]
    assert all(f"{name} (" in note for name in left_out), (left_out, note)


def test_a_message_fits_its_flattened_schema():
    """A real message, as the recorder writes it (JSON), validates against its channel's
    schema: flattening kept the fields' types and nesting."""
    from mrta_zenoh.messages import Header, PointCloud, Point2D
    msg = PointCloud(Header("robot1", 1.5, 3), (Point2D(0.5, -0.25), Point2D(1.0, 2.0)))
    (_, _, data), convert = json_channel(codec.encoding_for(PointCloud.TYPE_NAME))
    schema = json.loads(data)
    jsonschema.Draft202012Validator(schema).validate(json.loads(convert(codec.encode(msg))))
    assert schema["properties"]["points"]["items"]["properties"]["x"] == {"type": "number"}


def test_the_other_schemas_a_channel_carries_are_ones_the_apps_take():
    for name, data in (("liveliness", json.dumps(LIVELINESS_SCHEMA).encode()),
                       ROBOT_TASK_SCHEMA[::2], SUPERVISOR_SNAPSHOT_SCHEMA[::2],
                       ("unknown", json.dumps(object_schema("x_msgs/Unknown")).encode())):
        assert lint(json.loads(data), name) == [], name
    (_, _, data), _ = json_channel("application/msgpack;nobody_msgs/Unknown")
    assert lint(json.loads(data)) == []


@pytest.mark.parametrize("schema,expected", [
    ({"$ref": "#/$defs/A", "$defs": {"A": {"type": "object", "properties": {
        "x": {"anyOf": [{"type": "number"}, {"type": "null"}]},
        "b": {"anyOf": [{"$ref": "#/$defs/B"}, {"type": "null"}]},
        "e": {"enum": ["a", "b"]}, "m": {"type": "object", "additionalProperties": {
            "type": "integer"}},
        "t": {"type": "array", "prefixItems": [{"type": "number"}, {"type": "number"}]},
        "g": {"type": "array", "items": {"type": "array", "items": {"type": "number"}}}},
        "required": ["x", "b", "e", "m", "t", "g"]},
        "B": {"type": "object", "properties": {"y": {"type": "integer"}}, "required": ["y"]}}},
     {"x": {"type": "number"}, "b": {"type": "object", "properties": {"y": {"type": "integer"}},
                                     "required": ["y"]},
      "e": {"type": "string"},
      "m": {"type": "object", "properties": {}, "additionalProperties": {"type": "integer"}},
      "t": {"type": "array", "items": {"type": "number"}}}),
])
def test_flatten_inlines_references_and_declares_nullables_by_their_type(schema, expected):
    out = flatten(schema)
    assert out["properties"] == expected
    assert out["required"] == ["e", "m", "t"]  # nullable ones are not required; g is gone
    assert "g (an array of arrays" in out["description"]
    assert lint(out) == []
