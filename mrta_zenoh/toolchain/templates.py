"""Fill an architecture's config templates with a user's values (dissertation §3.3).

Values mirror the YAML that comes out: a mapping per `Params`, a scalar per `Param`, and a *list*
per `Array` (its length becomes the sibling `size`, its items become `<name with @index@>`).
A param with neither default nor fixed value is mandatory; every value is checked against its
type. `@task_id@` in an array marks the robot's task list: that array is sized and filled from the
tasks the robot was given, so the user never types them twice.
"""

from __future__ import annotations

import copy
from typing import Any

from ..errors import ConfigError
from ..yamlfile import did_you_mean
from .model import Array, Config, Node, Param, Params

ARRAY_SIZE = "@array_size@"
TASK_PLACEHOLDER = "@task_id@"
INDEX = "@index@"
# Entries of one array (sensors, behaviour sets, tasks): far beyond a robot's needs, and a bound
# on what an answers file of aliases (`- *sensor` a million times) can make the generator build.
MAX_ITEMS = 1000


def convert(type_: str | None, value: Any, where: str) -> Any:
    """A user value as the Python type the YAML should hold, or ConfigError."""
    if type_ in (None, "string"):
        if isinstance(value, (dict, list)):
            raise ConfigError(f"{where}: expected a string, got {type(value).__name__}")
        return "" if value is None else str(value)
    if type_ == "int":
        if isinstance(value, bool):
            raise ConfigError(f"{where}: expected an int, got {value!r}")
        try:
            if isinstance(value, float) and not value.is_integer():
                raise ValueError
            return int(str(value).strip()) if not isinstance(value, (int, float)) else int(value)
        except (TypeError, ValueError):
            raise ConfigError(f"{where}: expected an int, got {value!r}") from None
    if type_ == "double":
        if isinstance(value, bool):
            raise ConfigError(f"{where}: expected a double, got {value!r}")
        try:
            return float(value)
        except (TypeError, ValueError):
            raise ConfigError(f"{where}: expected a double, got {value!r}") from None
    if type_ == "bool":
        if isinstance(value, bool):
            return value
        text = str(value).strip().lower()
        if text in ("true", "yes", "1"):
            return True
        if text in ("false", "no", "0"):
            return False
        raise ConfigError(f"{where}: expected a bool (true/false), got {value!r}")
    raise ConfigError(f"{where}: unknown type {type_!r}")


def _uses_task_id(node: Node) -> bool:
    if isinstance(node, Param):
        return node.value == TASK_PLACEHOLDER
    return any(_uses_task_id(c) for c in node.children)


def instantiate(config: Config, values: dict | None, config_id: str, where: str,
                robot_tasks: list[str] | None = None) -> Config:
    """The filled config (arrays expanded, every param valued) or ConfigError naming the path."""
    kids = _fill(config.children, values or {}, where, robot_tasks)
    return Config(config_id, kids)


def _fill(children: list[Node], values: dict | list, where: str,
          robot_tasks: list[str] | None) -> list[Node]:
    arrays = [c for c in children if isinstance(c, Array)]
    if isinstance(values, list) and len(arrays) == 1:
        values = {_array_key(arrays[0]): values}  # `sensors: [...]` for size + sensor@index@
    if not isinstance(values, dict):
        raise ConfigError(f"{where}: expected a mapping of parameters, got {values!r:.80}")
    known = {c.name for c in children if not isinstance(c, Array)}
    array_keys = {_array_key(a): a for a in arrays}
    for key in values:
        if key not in known and key not in array_keys:
            raise ConfigError(f"{where}/{key}: unknown parameter"
                              + did_you_mean(key, list(known) + list(array_keys))
                              + f" (expected: {', '.join(sorted(known | set(array_keys)))})")
    size_of_array: dict[str, int] = {}
    expanded: dict[str, list[Node]] = {}
    for a in arrays:
        key = _array_key(a)
        items = values.get(key)
        if _uses_task_id(a) and robot_tasks is not None:
            given = items if isinstance(items, list) else []
            if items is not None and not isinstance(items, list):
                raise ConfigError(f"{where}/{key}: expected a list, got {items!r:.80}")
            if len(given) not in (0, len(robot_tasks)):
                raise ConfigError(f"{where}/{key}: one entry per task of the robot "
                                  f"({', '.join(robot_tasks)}), got {len(given)}")
            items = [dict(given[i]) if i < len(given) else {} for i in range(len(robot_tasks))]
            for i, task in enumerate(robot_tasks):
                items[i]["@task_id@"] = task
        elif items is None:
            items = []
        if not isinstance(items, list):
            raise ConfigError(f"{where}/{key}: expected a list (one item per {key} entry), "
                              f"got {items!r:.80}")
        if len(items) > MAX_ITEMS:
            raise ConfigError(f"{where}/{key}: {len(items):,} entries, more than {MAX_ITEMS:,}")
        out = []
        for i, item in enumerate(items):
            name = a.name.replace(INDEX, str(i))
            out.append(Params(name, _fill_item(a.children, item, f"{where}/{key}[{i}]", robot_tasks)))
        expanded[a.name] = out
        size_of_array[a.name] = len(items)
    result: list[Node] = []
    for child in children:
        if isinstance(child, Array):
            result.extend(expanded[child.name])
            continue
        path = f"{where}/{child.name}"
        if isinstance(child, Params):
            sub = values.get(child.name)
            result.append(Params(child.name, _fill(child.children, {} if sub is None else sub,
                                                   path, robot_tasks)))
            continue
        p = copy.copy(child)
        if p.value == ARRAY_SIZE:
            sizes = list(size_of_array.values())
            p.value = str(sizes[0] if sizes else 0)
        elif p.value == TASK_PLACEHOLDER:
            if child.name in values:
                raise ConfigError(f"{path}: filled from the robot's task list; do not set it")
        elif child.name in values:
            if p.value and "@" not in p.value:
                raise ConfigError(f"{path}: fixed by the architecture ({p.value!r}); do not set it")
            p.value = _to_text(convert(p.type, values[child.name], path))
        elif p.value and "@" not in p.value:
            pass  # fixed by the template
        elif p.default:
            p.value = _to_text(convert(p.type, p.default, path))
        else:
            raise ConfigError(f"{path}: mandatory parameter missing"
                              + (f" ({p.tool_tip})" if p.tool_tip else ""))
        result.append(p)
    return result


def _fill_item(children: list[Node], item: Any, where: str,
               robot_tasks: list[str] | None) -> list[Node]:
    if not isinstance(item, dict):
        raise ConfigError(f"{where}: expected a mapping, got {item!r:.80}")
    task = item.pop("@task_id@", None)
    filled = _fill(children, item, where, robot_tasks)
    if task is not None:
        for p in filled:
            if isinstance(p, Param) and p.value == TASK_PLACEHOLDER:
                p.value = task
    return filled


def _array_key(a: Array) -> str:
    """How values name an array: its item name without the index (`sensor@index@` → `sensor`)."""
    return a.name.replace(INDEX, "")


def _to_text(value: Any) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    return str(value)


def to_data(config: Config) -> dict:
    """A filled config as the YAML mapping the agent's parameter loader reads."""
    return _data(config.children)


def _data(children: list[Node]) -> dict:
    out: dict = {}
    for c in children:
        if isinstance(c, Param):
            out[c.name] = convert(c.type, c.value, c.name) if c.value is not None else None
        elif isinstance(c, Params):
            out[c.name] = _data(c.children)
        else:
            raise ConfigError(f"array {c.name!r} was not instantiated")
    return out
