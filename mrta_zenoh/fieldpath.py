"""Field paths: variant_topic_tools' syntax `header/frame_id`, `points/0/x` (a leading `/`
ignored), and the dotted one ROS 2 users type, `header.frame_id`, `points[0].x` or `points.0.x`.

A field name never holds a `.` or a `/`, so both spellings (even mixed) read the same path. A
path is parsed and checked once (when a monitor or `mrta echo --field` is set up) and then
resolved per sample with a flat loop: no string handling, never `eval`.
"""

from __future__ import annotations

import operator
import re
from typing import Any

from .errors import ConfigError
from .messages import GenericMessage, Message, fields_of


_INDEX = re.compile(r"\[(\d+)\]")  # points[0] → points/0
_SEPARATOR = re.compile(r"[/.]")


class FieldPathError(ConfigError, ValueError):
    """A field path that does not parse, or names no field: bad input (exit 2)."""


class FieldPath:
    __slots__ = ("text", "steps", "_attrs")

    def __init__(self, text: str, steps: tuple):
        self.text = text
        self.steps = steps
        # all-names paths read typed messages with one C-level attrgetter (the supervisor's hot
        # path); anything else (indices, generic messages, absent fields) goes through resolve()
        self._attrs = operator.attrgetter(".".join(steps)) \
            if steps and all(type(s) is str for s in steps) else None

    def get(self, msg: Any) -> Any:
        """resolve(), faster for typed messages and name-only paths."""
        if self._attrs is not None and type(msg) is not GenericMessage:
            try:
                return self._attrs(msg)
            except AttributeError:
                pass
        return self.resolve(msg)

    @classmethod
    def parse(cls, text: str) -> "FieldPath":
        stripped = text.strip()
        body = stripped.lstrip("/")
        if body == "":
            return cls(stripped, ())
        steps: list[str | int] = []
        for part in _SEPARATOR.split(_INDEX.sub(r"/\1", body)):
            if part == "":
                raise FieldPathError(f"field path {text!r} has an empty part (two separators "
                                     "in a row, or one at the end)")
            if part.isdigit():
                steps.append(int(part))
            elif part.isidentifier():
                steps.append(part)
            else:
                raise FieldPathError(
                    f"field path {text!r}: part {part!r} is neither a field name nor an index"
                )
        return cls(stripped, tuple(steps))

    def __repr__(self) -> str:
        return f"FieldPath({self.text!r})"

    def __str__(self) -> str:
        return self.text

    def resolve(self, msg: Any) -> Any:
        """The value at this path in a message (typed or generic); FieldPathError if absent."""
        value = msg.data if type(msg) is GenericMessage else msg
        for i, step in enumerate(self.steps):
            try:
                if type(step) is int:
                    if isinstance(value, (list, tuple)):
                        value = value[step]
                    else:
                        raise TypeError
                elif type(value) is dict:
                    value = value[step]
                elif isinstance(value, Message):
                    value = getattr(value, step)
                else:
                    raise TypeError
            except (KeyError, IndexError, AttributeError, TypeError):
                raise FieldPathError(self._explain(i, value)) from None
        return value

    def validate(self, cls: type[Message]) -> None:
        """Check the path against a message class before any sample arrives."""
        kind, current = "message", cls  # what the path points at so far
        for i, step in enumerate(self.steps):
            if kind == "list":
                if type(step) is not int:
                    raise FieldPathError(self._explain(i, "list"))
                if current is None:  # a list of scalars: an index ends the path
                    kind = "scalar"
                else:
                    kind = "message"
                continue
            if kind == "scalar" or type(step) is int:
                raise FieldPathError(self._explain(i, current if kind == "message" else "scalar"))
            spec = fields_of(current).get(step)
            if spec is None:
                raise FieldPathError(self._explain(i, current))
            field_kind, sub = spec
            if field_kind == "message":
                current = sub
            elif field_kind == "list":
                kind, current = "list", sub
            else:
                kind = "scalar"

    def _explain(self, i: int, at: Any) -> str:
        done = "/".join(str(s) for s in self.steps[:i]) or "(the message)"
        part = self.steps[i]
        return f"field path {self.text!r}: no {part!r} in {done}; {_describe(at)}"


def _is_message_class(x: Any) -> bool:
    return isinstance(x, type) and issubclass(x, Message)


def _describe(at: Any) -> str:
    if _is_message_class(at):
        return f"fields there: {', '.join(at.__struct_fields__)}"
    if isinstance(at, Message):
        return f"fields there: {', '.join(at.__struct_fields__)}"
    if isinstance(at, dict):
        return f"fields there: {', '.join(map(str, at)) or '(none)'}"
    if at == "list" or isinstance(at, (list, tuple)):
        n = "" if at == "list" else f" of {len(at)} item{'' if len(at) == 1 else 's'}"
        return f"it is a list{n}: use an index"
    return f"it is a plain value ({'scalar' if at == 'scalar' else type(at).__name__}) with no fields"
