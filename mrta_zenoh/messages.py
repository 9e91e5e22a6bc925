"""Typed messages: frozen msgspec Structs, each with the type name that travels on the wire.

The type name is what a generic subscriber (the supervisor, `mrta echo`) reads to know what it
received, as variant_topic_tools read the ROS connection header. Field names follow the common
ROS messages so field paths written for the original (`header/frame_id`) still work.

Declaring a type (the same for this core, the architectures, the applications and a third party):

    @message("my_msgs/Ping")
    class Ping(Message):
        header: Header
        count: int

and list it in the `mrta.messages` entry-point group (name = type name, value = `module:Class`),
so that every process — echo, supervise, record, plot — decodes it in a fresh interpreter,
whatever it happened to import before. The wire format is in docs/wire-format.md.

A field without a default is mandatory on the wire: a payload that lacks it is rejected. The
standard types below declare no defaults for that reason. A float annotated `Finite` rejects NaN
and ±inf on decoding, and on construction through `checked()`: physical quantities (stamps,
poses, velocities) use it, so one bad sample cannot poison a robot's state.
"""

from __future__ import annotations

import importlib
import logging
import sys
import threading
import typing
from typing import Annotated, Any, ClassVar

import msgspec

from mrta_zenoh.installed import entry_points  # the metadata read once, as every reader

log = logging.getLogger("mrta.messages")

ENTRY_POINT_GROUP = "mrta.messages"

# The largest finite float: msgspec checks ge/le before building the value, and NaN fails both.
_FMAX = sys.float_info.max
Finite = Annotated[float, msgspec.Meta(ge=-_FMAX, le=_FMAX)]


class Message(msgspec.Struct, frozen=True, forbid_unknown_fields=True, gc=False):
    """Base of every typed message. Subclasses inherit frozen, forbid_unknown_fields and
    gc=False: a frozen message of scalars and other messages cannot form a reference cycle, so
    the cycle collector need not track the hundreds of thousands decoded per second."""

    TYPE_NAME: ClassVar[str] = ""


class IndexedMessage(Message, kw_only=True, frozen=True):
    """A message that names robots and tasks by their index in the run's instance (SSI's rounds
    and bids, CBBA's bids): small on the wire, and meaningless on another instance — robot 2 of
    one is not robot 2 of another. So it says which instance it counts in: `instance`, the
    digest of the sender's (mrta_zenoh.instances.Loaded.digest). The agent runtime stamps it on
    every such message it sends and refuses one whose digest is not its own robot's, counting it
    (`ignored_other_instance`), instead of misreading it. Keyword-only, so it comes after the
    subclass's own fields and positional construction is unchanged."""

    instance: str = ""


_REGISTRY: dict[str, type[Message]] = {}
_lock = threading.Lock()
# Loading imports modules whose @message takes `_lock`, and such a module may itself decode
# while it is imported: hence a separate, re-entrant lock for loading, and `_loading` so that a
# re-entrant call returns at once instead of loading the group a second time.
_load_lock = threading.RLock()
_loading = False
_entry_points_loaded = False  # set only once every entry point has been imported
_entry_point_problems: list[str] = []


def message(type_name: str):
    """Class decorator: register a Message subclass under `type_name` (once per process)."""

    def wrap(cls):
        if not (isinstance(cls, type) and issubclass(cls, Message)):
            raise TypeError(f"@message({type_name!r}) needs a Message subclass, got {cls!r}")
        with _lock:
            known = _REGISTRY.get(type_name)
            if known is not None and known is not cls:
                raise ValueError(f"message type {type_name!r} is already registered "
                                 f"by {known.__module__}.{known.__qualname__}")
            cls.TYPE_NAME = type_name
            _REGISTRY[type_name] = cls
        return cls

    return wrap


def load_entry_points() -> list[str]:
    """Import every module listed under `mrta.messages`; returns the problems met (once).

    Threads that ask while another is loading wait for it: were they told "loaded" early, they
    would see a partial registry and decode a registered type as GenericMessage for good (the
    decoder of an encoding is resolved once and cached by its caller)."""
    global _entry_points_loaded, _loading
    if _entry_points_loaded:  # the fast path: no lock once loaded
        return _entry_point_problems
    with _load_lock:
        if _entry_points_loaded or _loading:  # loaded meanwhile, or this thread is loading
            return _entry_point_problems
        _loading = True
        try:
            _load_group()
        finally:  # after an unexpected error too: the group is tried once per process
            _loading = False
            _entry_points_loaded = True
    for p in _entry_point_problems:
        log.warning("%s", p)
    return _entry_point_problems


def _load_group() -> None:
    for ep in entry_points(group=ENTRY_POINT_GROUP):
        module, _, attr = ep.value.partition(":")
        try:
            cls = getattr(importlib.import_module(module), attr) if attr else None
        except (ImportError, AttributeError) as exc:
            _entry_point_problems.append(f"message entry point {ep.name!r} ({ep.value}): {exc}")
            continue
        if cls is None or getattr(cls, "TYPE_NAME", None) != ep.name:
            _entry_point_problems.append(
                f"message entry point {ep.name!r} ({ep.value}) does not name a class registered "
                f"with @message({ep.name!r})")


def message_class(type_name: str) -> type[Message] | None:
    """The registered class for a type name, or None when no installed package declares it."""
    cls = _REGISTRY.get(type_name)
    if cls is None and not _entry_points_loaded:
        load_entry_points()
        cls = _REGISTRY.get(type_name)
    return cls


def registered_types() -> dict[str, type[Message]]:
    """Every type this process can decode: the core's and those of every installed package."""
    load_entry_points()
    return dict(_REGISTRY)


def checked(msg: Message) -> Message:
    """The message itself, after the checks decoding would apply (finite floats, types).

    Construction does not validate (msgspec Structs don't); code that builds a message from
    values it did not produce itself can call this to fail early instead of on the receiver."""
    from .codec import struct_decoder  # codec imports this module

    struct_decoder(type(msg))  # msgspec's type information built once, under codec's lock
    return msgspec.convert(msgspec.to_builtins(msg), type(msg))


class GenericMessage(msgspec.Struct, frozen=True):
    """A sample of a type this process does not know: its type name and the decoded map.

    Generic tools (echo, supervisor, recorder) can still read any field of it by path.
    """

    type_name: str
    data: dict

    TYPE_NAME: ClassVar[str] = ""


def fields_of(cls: type[Message]) -> dict[str, tuple[str, type | None]]:
    """Field name → (kind, message class): kind is "message", "list" (of the class, or of
    scalars when None) or "scalar". For field-path checks and schema generation."""
    out: dict[str, tuple[str, type | None]] = {}
    hints = typing.get_type_hints(cls)
    for name in cls.__struct_fields__:
        t = hints[name]
        if isinstance(t, type) and issubclass(t, Message):
            out[name] = ("message", t)
        elif typing.get_origin(t) in (tuple, list):
            item = typing.get_args(t)[0]
            out[name] = ("list", item if isinstance(item, type) and issubclass(item, Message)
                         else None)
        else:
            out[name] = ("scalar", None)
    return out


def is_message(value: Any) -> bool:
    return isinstance(value, (Message, GenericMessage))


# ---------------------------------------------------------------- standard types


@message("std_msgs/Header")
class Header(Message):
    frame_id: str
    stamp: Finite  # seconds on the sender's clock (wall or simulation)
    seq: int


@message("rosgraph_msgs/Clock")
class Clock(Message):
    """Simulated time. `source` names the run that publishes it (empty from other clients),
    so followers can tell a restarted simulator from a late or forged sample."""

    stamp: Finite
    source: str = ""


@message("geometry_msgs/Pose2D")
class Pose2D(Message):
    x: Finite
    y: Finite
    theta: Finite


@message("mrta_msgs/Twist")
class Twist(Message):
    """Planar velocity command: linear (m/s, along the robot's x) and angular (rad/s)."""

    linear: Finite
    angular: Finite


@message("mrta_msgs/Odometry")
class Odometry(Message):
    header: Header
    pose: Pose2D
    twist: Twist


@message("mrta_msgs/Point2D")
class Point2D(Message):
    x: Finite
    y: Finite


@message("mrta_msgs/PointCloud")
class PointCloud(Message):
    """Sonar returns in the robot frame, metres, like RosAria's `sonar` topic."""

    header: Header
    points: tuple[Point2D, ...]
