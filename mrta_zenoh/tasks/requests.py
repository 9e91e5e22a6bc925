"""Requests as a person writes them: `--set FIELD=VALUE` pairs, a JSON object, a file of many
(line-aware: an error names file, line and key)."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import yaml

from ..errors import ConfigError
from ..yamlfile import load_yaml
from .api import TaskRequest
from .messages import Op


def task_fields(sets: tuple[str, ...], as_json: str | None) -> dict[str, Any]:
    """The fields of one task from --set pairs (YAML values) over a --json object."""
    fields: dict[str, Any] = {}
    if as_json is not None:
        try:
            fields = json.loads(as_json)
        except ValueError as exc:
            raise ConfigError(f"--json: not JSON: {exc}") from None
        if not isinstance(fields, dict):
            raise ConfigError("--json: the task's fields must be a JSON object")
    for pair in sets:
        key, sep, value = pair.partition("=")
        if not sep or not key.strip():
            raise ConfigError(f"--set {pair!r}: expected FIELD=VALUE")
        try:
            fields[key.strip()] = yaml.safe_load(value)
        except yaml.YAMLError:
            raise ConfigError(f"--set {pair!r}: the value is not YAML") from None
    return fields


def requests_from_file(path: Path) -> list[TaskRequest]:
    """Submissions from a file: a mapping id → fields, or a list of objects with an `id`; each
    may say its `priority`."""
    doc = load_yaml(path)
    data = doc.data
    if isinstance(data, dict) and isinstance(data.get("tasks"), (dict, list)):
        data, base = data["tasks"], ("tasks",)
    else:
        base = ()
    items: list[tuple[tuple, str, Any]]
    if isinstance(data, dict):
        items = [(base + (k,), str(k), v) for k, v in data.items()]
    elif isinstance(data, list):
        items = []
        for i, v in enumerate(data):
            if not isinstance(v, dict) or not isinstance(v.get("id"), str):
                raise doc.error(base + (i,), "each entry needs an `id` (a string)")
            items.append((base + (i,), v["id"], {k: x for k, x in v.items() if k != "id"}))
    else:
        raise ConfigError("expected tasks: a mapping id → fields, or a list with ids",
                          file=str(path))
    out = []
    for where, tid, fields in items:
        if not isinstance(fields, dict):
            raise doc.error(where, "a task's fields must be a mapping")
        priority = fields.pop("priority", 0)
        if type(priority) is not int:
            raise doc.error(where + ("priority",), f"priority must be an integer, got {priority!r}")
        out.append(TaskRequest(Op.SUBMIT, tid, fields, priority))
    if not out:
        raise ConfigError("no tasks in it", file=str(path))
    return out
