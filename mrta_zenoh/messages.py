"""Typed messages: small frozen dataclasses, each with the type name that travels on the wire.

The type name is what a generic subscriber (the supervisor, `mrta echo`) reads to know what it
received, as variant_topic_tools read the ROS connection header. Field names follow alliance_msgs
and the common ROS messages so field paths written for the original (`header/frame_id`) still work.

A message class declares its fields with plain annotations; `@message("pkg/Type")` turns it into a
frozen, slotted dataclass and records a field spec that the codec uses for strict decoding.
Sequences are tuples so that a message really is immutable.
"""

from __future__ import annotations

import dataclasses
import typing
from dataclasses import dataclass, field
from typing import Any, ClassVar

# Field kinds understood by the codec.
FLOAT, INT, STR, BOOL, MESSAGE, MESSAGE_LIST, FLOAT_LIST = (
    "float", "int", "str", "bool", "message", "message[]", "float[]",
)


@dataclass(frozen=True, slots=True)
class FieldSpec:
    name: str
    kind: str
    message_class: type | None = None  # for MESSAGE / MESSAGE_LIST


class Message:
    """Base of every typed message (a marker; the dataclass machinery does the work)."""

    __slots__ = ()
    TYPE_NAME: ClassVar[str] = ""
    FIELDS: ClassVar[tuple[FieldSpec, ...]] = ()


_REGISTRY: dict[str, type[Message]] = {}

_SCALARS = {float: FLOAT, int: INT, str: STR, bool: BOOL}


def _kind_of(annotation: Any) -> tuple[str, type | None]:
    if annotation in _SCALARS:
        return _SCALARS[annotation], None
    if isinstance(annotation, type) and issubclass(annotation, Message):
        return MESSAGE, annotation
    origin = typing.get_origin(annotation)
    if origin is tuple:
        args = typing.get_args(annotation)
        if len(args) == 2 and args[1] is Ellipsis:
            item = args[0]
            if isinstance(item, type) and issubclass(item, Message):
                return MESSAGE_LIST, item
            if item is float:
                return FLOAT_LIST, None
    raise TypeError(f"unsupported message field annotation {annotation!r}")


def message(type_name: str):
    """Class decorator: make a frozen slotted dataclass and register it under `type_name`."""

    def wrap(cls):
        if type_name in _REGISTRY:
            raise ValueError(f"message type {type_name!r} is already registered")
        cls = dataclass(frozen=True, slots=True)(cls)
        hints = typing.get_type_hints(cls)
        specs = []
        for f in dataclasses.fields(cls):
            kind, sub = _kind_of(hints[f.name])
            specs.append(FieldSpec(f.name, kind, sub))
        cls.TYPE_NAME = type_name
        cls.FIELDS = tuple(specs)
        _REGISTRY[type_name] = cls
        return cls

    return wrap


def message_class(type_name: str) -> type[Message] | None:
    """The registered class for a type name, or None when the type is not known here."""
    return _REGISTRY.get(type_name)


def registered_types() -> dict[str, type[Message]]:
    return dict(_REGISTRY)


@dataclass(frozen=True, slots=True)
class GenericMessage:
    """A sample of a type this process does not know: its type name and the decoded map.

    Generic tools (echo, supervisor, recorder) can still read any field of it by path.
    """

    type_name: str
    data: dict

    TYPE_NAME: ClassVar[str] = ""


# ---------------------------------------------------------------- common messages


@message("std_msgs/Header")
class Header(Message):
    frame_id: str = ""
    stamp: float = 0.0  # seconds on the sender's clock (wall or simulation)
    seq: int = 0


@message("rosgraph_msgs/Clock")
class Clock(Message):
    stamp: float = 0.0


@message("geometry_msgs/Pose2D")
class Pose2D(Message):
    x: float = 0.0
    y: float = 0.0
    theta: float = 0.0


@message("mrta_msgs/Twist")
class Twist(Message):
    """Planar velocity command: linear (m/s, along the robot's x) and angular (rad/s)."""

    linear: float = 0.0
    angular: float = 0.0


@message("mrta_msgs/Odometry")
class Odometry(Message):
    header: Header = field(default_factory=Header)
    pose: Pose2D = field(default_factory=Pose2D)
    twist: Twist = field(default_factory=Twist)


@message("mrta_msgs/Point2D")
class Point2D(Message):
    x: float = 0.0
    y: float = 0.0


@message("mrta_msgs/PointCloud")
class PointCloud(Message):
    """Sonar returns in the robot frame, metres, like RosAria's `sonar` topic."""

    header: Header = field(default_factory=Header)
    points: tuple[Point2D, ...] = ()


@message("mrta_msgs/Bumper")
class Bumper(Message):
    """Contact state of a simulated robot (RosAria's bumper_state, reduced to what a 2-D body has).

    `stalled`: the motors push but the robot does not move; `collisions`: contacts begun so far."""

    header: Header = field(default_factory=Header)
    stalled: bool = False
    contact: bool = False
    collisions: int = 0


# ---------------------------------------------------------------- alliance_msgs


@message("alliance_msgs/InterRobotCommunication")
class InterRobotCommunication(Message):
    header: Header = field(default_factory=Header)
    task_id: str = ""
    expected_duration: float = 0.0


@message("alliance_msgs/Motivation")
class Motivation(Message):
    header: Header = field(default_factory=Header)
    task_id: str = ""
    impatience: float = 0.0
    acquiescent: bool = False
    suppressed: bool = False
    resetted: bool = False
    applicable: bool = False
    motivation: float = 0.0
    threshold: float = 0.0
    active: bool = False


@message("alliance_msgs/SensoryFeedback")
class SensoryFeedback(Message):
    header: Header = field(default_factory=Header)
    task_id: str = ""
    applicable: bool = False
