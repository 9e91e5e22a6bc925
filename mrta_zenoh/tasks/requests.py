"""Requests as a person writes them: `--set FIELD=VALUE` pairs, a JSON object, a file of many
(line-aware: an error names file, line and key) — and an Open-RMF `task_request` (the JSON its
fleet adapters take: `category`, `description`, optional `priority`), mapped to a point task.

Open-RMF places are waypoint names of a navigation graph; a world of ours has none, so a place
is given as its coordinates, "X,Y" (metres). What has no meaning in a simulated run is refused,
not dropped: a wall-clock `unix_millis_earliest_start_time` (a simulated run's instants are not
the epoch's)."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import yaml

from ..errors import ConfigError
from ..yamlfile import load_yaml
from .api import TaskRequest
from .messages import Op


RMF_CATEGORIES = ("delivery", "compose")   # compose: its go_to_place activity


def _place(value: Any, where: str) -> list[float]:
    name = value.get("waypoint") if isinstance(value, dict) else value
    if isinstance(name, str):
        x, sep, y = name.partition(",")
        try:
            if sep:
                return [float(x), float(y)]
        except ValueError:
            pass
    raise ConfigError(f"{where}: place {name!r:.60}: this world has no named places; give the "
                      "place as \"X,Y\" (metres)")


def from_rmf(request: dict[str, Any]) -> tuple[dict[str, Any], int | None]:
    """An Open-RMF task_request → (the task's fields, its priority or None)."""
    category, desc = request.get("category"), request.get("description")
    if category not in RMF_CATEGORIES or not isinstance(desc, dict):
        raise ConfigError(f"task_request: category {category!r}: expected delivery, or compose "
                          "with a go_to_place activity, and a description object")
    if request.get("unix_millis_earliest_start_time"):
        raise ConfigError("task_request: unix_millis_earliest_start_time is wall-clock time, "
                          "which a simulated run has no instant for: give `earliest` (s)")
    if category == "delivery":
        drop = desc.get("dropoff")
        if not isinstance(drop, dict):
            raise ConfigError("task_request: a delivery needs description.dropoff.place")
        fields = {"position": _place(drop.get("place"), "description.dropoff")}
    else:
        phases = desc.get("phases") if desc.get("category") == "go_to_place" else None
        activity = (phases[0].get("activity") if isinstance(phases, list) and phases
                    and isinstance(phases[0], dict) else None)
        if not isinstance(activity, dict) or activity.get("category") != "go_to_place":
            raise ConfigError("task_request: compose: expected description.category go_to_place "
                              "with phases[0].activity of category go_to_place")
        fields = {"position": _place(activity.get("description"),
                                     "description.phases[0].activity.description")}
    priority = request.get("priority")
    if isinstance(priority, dict):
        priority = priority.get("value")
    if priority is not None and type(priority) is not int:
        raise ConfigError(f"task_request: priority {priority!r}: expected an integer value")
    return fields, priority


def task_fields(sets: tuple[str, ...], as_json: str | None
                ) -> tuple[dict[str, Any], int | None]:
    """The fields of one task from --set pairs (YAML values) over a --json object (an
    Open-RMF task_request mapped by from_rmf), and the priority the request states (None)."""
    fields: dict[str, Any] = {}
    priority = None
    if as_json is not None:
        try:
            fields = json.loads(as_json)
        except ValueError as exc:
            raise ConfigError(f"--json: not JSON: {exc}") from None
        if not isinstance(fields, dict):
            raise ConfigError("--json: the task's fields must be a JSON object")
        if "category" in fields and "description" in fields:
            fields, priority = from_rmf(fields)
    for pair in sets:
        key, sep, value = pair.partition("=")
        if not sep or not key.strip():
            raise ConfigError(f"--set {pair!r}: expected FIELD=VALUE")
        try:
            fields[key.strip()] = yaml.safe_load(value)
        except yaml.YAMLError:
            raise ConfigError(f"--set {pair!r}: the value is not YAML") from None
    return fields, priority


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
