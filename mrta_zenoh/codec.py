"""The wire format (DESIGN §9): a msgpack map of the message's fields, typed by the encoding.

Encoding string: `application/msgpack;<type name>`. Decoding is strict so that a bad sample is
rejected whole, with an error that says what was wrong, instead of becoming a half-built object
that fails later somewhere else. Per-type encoders and decoders are built once from the message's
field spec; the hot path is one msgpack call plus a flat loop over the fields.
"""

from __future__ import annotations

from typing import Any, Callable

import msgpack

from .messages import (
    BOOL, FLOAT, FLOAT_LIST, INT, MESSAGE, MESSAGE_LIST, STR,
    GenericMessage, Message, message_class,
)

ENCODING_PREFIX = "application/msgpack"

# Limits that make an absurd payload fail fast instead of allocating without bound.
MAX_PAYLOAD_BYTES = 4 * 1024 * 1024
MAX_STR_LEN = 64 * 1024
MAX_ARRAY_LEN = 100_000
MAX_MAP_LEN = 1_000


class DecodeError(ValueError):
    """A payload that cannot become a message. `path` names the offending field, if any."""

    def __init__(self, message: str, path: str = ""):
        super().__init__(f"{path}: {message}" if path else message)
        self.path = path


class NotMsgpack(DecodeError):
    pass


class TruncatedPayload(DecodeError):
    pass


class PayloadTooLarge(DecodeError):
    pass


class NotAMap(DecodeError):
    pass


class MissingField(DecodeError):
    pass


class UnknownField(DecodeError):
    pass


class WrongFieldType(DecodeError):
    pass


class BadEncoding(DecodeError):
    pass


def encoding_for(type_name: str) -> str:
    return f"{ENCODING_PREFIX};{type_name}"


def type_from_encoding(encoding: str) -> str:
    """The type name carried in an encoding string; BadEncoding if it is not our wire format."""
    prefix, sep, schema = encoding.partition(";")
    if prefix != ENCODING_PREFIX:
        raise BadEncoding(f"encoding {encoding!r} is not {ENCODING_PREFIX}")
    if not sep or not schema:
        raise BadEncoding(f"encoding {encoding!r} carries no message type name")
    return schema


# ---------------------------------------------------------------- encoding

_encoders: dict[type, Callable[[Any], dict]] = {}


def _encoder(cls: type[Message]) -> Callable[[Any], dict]:
    """A function building the wire map of `cls`, generated from its field spec.

    Generated source (as dataclasses and namedtuple do) because a generic per-field loop cost
    three times as much, and encoding sits on every publish.
    """
    enc = _encoders.get(cls)
    if enc is not None:
        return enc
    env: dict[str, Any] = {}
    items = []
    for spec in cls.FIELDS:
        n = spec.name
        if spec.kind == MESSAGE:
            env[f"e_{n}"] = _encoder(spec.message_class)
            items.append(f"{n!r}: e_{n}(m.{n})")
        elif spec.kind == MESSAGE_LIST:
            env[f"e_{n}"] = _encoder(spec.message_class)
            items.append(f"{n!r}: [e_{n}(x) for x in m.{n}]")
        elif spec.kind == FLOAT_LIST:
            items.append(f"{n!r}: list(m.{n})")
        else:
            items.append(f"{n!r}: m.{n}")
    src = f"def enc(m):\n    return {{{', '.join(items)}}}\n"
    exec(compile(src, f"<encoder {cls.TYPE_NAME}>", "exec"), env)  # noqa: S102 - our own spec
    enc = _encoders[cls] = env["enc"]
    return enc


def encoder_for(cls: type[Message]) -> Callable[[Any], dict]:
    return _encoder(cls)


def to_dict(msg: Message | GenericMessage) -> dict:
    """The message as the plain map that goes on the wire (also used for JSON output)."""
    if isinstance(msg, GenericMessage):
        return msg.data
    return _encoder(type(msg))(msg)


def encode(msg: Message | GenericMessage) -> bytes:
    return msgpack.packb(to_dict(msg), use_bin_type=True)


# ---------------------------------------------------------------- decoding

_decoders: dict[type, Callable[[Any, str], Any]] = {}
_fast_decoders: dict[type, Callable[[Any], Any]] = {}


class _Invalid(Exception):
    """Raised by a generated fast decoder; the checking decoder then finds and names the fault."""


def _fast_decoder(cls: type[Message]) -> Callable[[Any], Any]:
    """A generated decoder for well-formed input: straight-line type checks, no path strings.

    Any doubt raises _Invalid and `decode` reruns the checking decoder, which produces the precise
    error. Valid input therefore costs one pass, invalid input two (rare, already counted).
    """
    dec = _fast_decoders.get(cls)
    if dec is not None:
        return dec
    env: dict[str, Any] = {"cls": cls, "Invalid": _Invalid, "dict": dict, "str": str,
                           "float": float, "int": int, "bool": bool, "list": list, "tuple": tuple}
    lines = ["def dec(d):",
             "    if type(d) is not dict or len(d) != %d:" % len(cls.FIELDS),
             "        raise Invalid",
             "    try:"]
    lines += [f"        v_{s.name} = d[{s.name!r}]" for s in cls.FIELDS]
    lines += ["    except KeyError:", "        raise Invalid from None"]
    for spec in cls.FIELDS:
        v = f"v_{spec.name}"
        if spec.kind == FLOAT:
            lines += [f"    if type({v}) is not float:",
                      f"        if type({v}) is int:", f"            {v} = float({v})",
                      "        else:", "            raise Invalid"]
        elif spec.kind in (STR, BOOL, INT):
            lines += [f"    if type({v}) is not {spec.kind}:", "        raise Invalid"]
        elif spec.kind == MESSAGE:
            env[f"d_{spec.name}"] = _fast_decoder(spec.message_class)
            lines += [f"    {v} = d_{spec.name}({v})"]
        elif spec.kind == MESSAGE_LIST:
            env[f"d_{spec.name}"] = _fast_decoder(spec.message_class)
            lines += [f"    if type({v}) is not list:", "        raise Invalid",
                      f"    {v} = tuple([d_{spec.name}(x) for x in {v}])"]
        else:  # FLOAT_LIST: the checking decoder handles int/float mixes
            lines += ["    raise Invalid"]
    # Build through the slot descriptors: a frozen dataclass __init__ costs ~70% more, and the
    # values were just checked, which is all its __init__ would add (no __post_init__ exists).
    env["new"] = object.__new__
    lines.append("    o = new(cls)")
    for spec in cls.FIELDS:
        env[f"set_{spec.name}"] = getattr(cls, spec.name).__set__
        lines.append(f"    set_{spec.name}(o, v_{spec.name})")
    lines.append("    return o")
    exec(compile("\n".join(lines) + "\n", f"<decoder {cls.TYPE_NAME}>", "exec"), env)  # noqa: S102
    dec = _fast_decoders[cls] = env["dec"]
    return dec


def _type_name(v: Any) -> str:
    return type(v).__name__


def _decoder(cls: type[Message]) -> Callable[[Any, str], Any]:
    dec = _decoders.get(cls)
    if dec is not None:
        return dec
    names = frozenset(s.name for s in cls.FIELDS)
    plan = []
    for spec in cls.FIELDS:
        sub = _decoder(spec.message_class) if spec.message_class is not None else None
        plan.append((spec.name, spec.kind, sub))
    nfields = len(plan)
    type_name = cls.TYPE_NAME

    def dec(data: Any, where: str):
        if type(data) is not dict:
            raise NotAMap(f"expected a map for {type_name}, got {_type_name(data)}", where)
        if len(data) != nfields:
            _report_mismatch(data, names, type_name, where)
        values = []
        for name, kind, sub in plan:
            try:
                v = data[name]
            except KeyError:
                raise MissingField(f"missing field of {type_name}", _join(where, name)) from None
            t = type(v)
            if kind == FLOAT:
                if t is not float:
                    if t is int:  # integers are valid numbers for other clients
                        v = float(v)
                    else:
                        raise _wrong(where, name, "float", v)
            elif kind == STR:
                if t is not str:
                    raise _wrong(where, name, "str", v)
            elif kind == BOOL:
                if t is not bool:
                    raise _wrong(where, name, "bool", v)
            elif kind == INT:
                if t is not int:
                    raise _wrong(where, name, "int", v)
            elif kind == MESSAGE:
                v = sub(v, _join(where, name))
            elif kind == MESSAGE_LIST:
                if t is not list:
                    raise _wrong(where, name, "list", v)
                path = _join(where, name)
                v = tuple([sub(x, f"{path}/{i}") for i, x in enumerate(v)])
            else:  # FLOAT_LIST
                if t is not list:
                    raise _wrong(where, name, "list", v)
                out = []
                for i, x in enumerate(v):
                    if type(x) is float or type(x) is int:
                        out.append(float(x))
                    else:
                        raise _wrong(where, f"{name}/{i}", "float", x)
                v = tuple(out)
            values.append(v)
        return cls(*values)

    _decoders[cls] = dec
    return dec


def _join(where: str, name: str) -> str:
    return f"{where}/{name}" if where else name


def _wrong(where: str, name: str, expected: str, value: Any) -> WrongFieldType:
    return WrongFieldType(f"expected {expected}, got {_type_name(value)} {value!r:.40}", _join(where, name))


def _report_mismatch(data: dict, names: frozenset, type_name: str, where: str) -> None:
    extra = [k for k in data if k not in names]
    if extra:
        raise UnknownField(
            f"unknown field {extra[0]!r} for {type_name} (fields: {', '.join(sorted(names))})", where
        )
    # Fewer keys than fields: the field loop reports which one is missing.


def unpack(payload: bytes) -> Any:
    """msgpack → Python with size limits; errors become DecodeError subclasses."""
    if len(payload) > MAX_PAYLOAD_BYTES:
        raise PayloadTooLarge(f"payload of {len(payload)} bytes exceeds {MAX_PAYLOAD_BYTES}")
    try:
        return msgpack.unpackb(
            payload, raw=False, strict_map_key=True,
            max_str_len=MAX_STR_LEN, max_bin_len=MAX_STR_LEN,
            max_array_len=MAX_ARRAY_LEN, max_map_len=MAX_MAP_LEN, max_ext_len=0,
        )
    except msgpack.ExtraData:
        raise NotMsgpack("trailing bytes after the msgpack value") from None
    except msgpack.FormatError:
        raise NotMsgpack("not msgpack: invalid or reserved type byte") from None
    except msgpack.StackError:
        raise NotMsgpack("not msgpack: nesting too deep") from None
    except ValueError as exc:  # msgpack raises ValueError for size limits and short input
        text = str(exc)
        if "incomplete" in text:
            raise TruncatedPayload("payload ends in the middle of a msgpack value") from None
        if "exceeds max" in text:
            raise PayloadTooLarge(f"a msgpack string, array or map is too large ({text})") from None
        raise NotMsgpack(f"not msgpack: {text}") from None
    except TypeError as exc:
        raise NotMsgpack(f"not msgpack: {exc}") from None


def decode(type_name: str, payload: bytes) -> Message | GenericMessage:
    """Strictly decode a payload of the named type; unknown types become GenericMessage."""
    data = unpack(payload)
    cls = message_class(type_name)
    if cls is None:
        if type(data) is not dict:
            raise NotAMap(f"expected a map for {type_name}, got {_type_name(data)}")
        return GenericMessage(type_name, data)
    try:
        return _fast_decoder(cls)(data)
    except _Invalid:
        return _decoder(cls)(data, "")


def decoder_for(encoding: str) -> tuple[str, Callable[[bytes], Any]]:
    """(type name, payload → message) for an encoding string: resolved once, used per sample."""
    type_name = type_from_encoding(encoding)
    cls = message_class(type_name)
    if cls is None:
        return type_name, lambda payload: decode(type_name, payload)
    fast, checking = _fast_decoder(cls), _decoder(cls)

    def dec(payload: bytes) -> Any:
        data = unpack(payload)
        try:
            return fast(data)
        except _Invalid:
            return checking(data, "")

    return type_name, dec


def from_dict(cls: type[Message], data: Any) -> Message:
    """Build a message from a plain map with the same strict checks as decoding."""
    try:
        return _fast_decoder(cls)(data)
    except _Invalid:
        return _decoder(cls)(data, "")
