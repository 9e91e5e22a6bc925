"""The wire format (docs/wire-format.md): a msgpack map of the message's fields, typed by the encoding.

Encoding string: `application/msgpack;<type name>`. msgspec does the work: it encodes Structs to
the same maps the hand-written codec did, and decodes strictly (types, required and unknown
fields, finite floats) with the field path of the fault. This module maps its errors onto the
DecodeError classes callers count and report, so a bad sample is rejected whole with an error
that says what was wrong, never half-built.
"""

from __future__ import annotations

import re
import sys
import threading
from dataclasses import dataclass
from typing import Any, Callable

import msgspec

from .messages import GenericMessage, Message, message_class

ENCODING_PREFIX = "application/msgpack"

# A payload larger than this is refused before it is parsed (a 10⁶-point cloud is ~19 MB).
MAX_PAYLOAD_BYTES = 4 * 1024 * 1024


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


class NonFinite(WrongFieldType):
    """NaN or ±inf where a physical quantity is expected."""


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

_encoder = msgspec.msgpack.Encoder()
_plain = msgspec.msgpack.Decoder()
encode_struct = _encoder.encode  # the hot path: one C call


def to_dict(msg: Message | GenericMessage) -> dict:
    """The message as the plain map that goes on the wire (also used for JSON output)."""
    if type(msg) is GenericMessage:
        return msg.data
    return _plain.decode(_encoder.encode(msg))  # exactly the wire map (lists, not tuples)


def encode(msg: Message | GenericMessage) -> bytes:
    if type(msg) is GenericMessage:
        return _encoder.encode(msg.data)
    return _encoder.encode(msg)


# ---------------------------------------------------------------- decoding

@dataclass(frozen=True)
class ValidationFault:
    """msgspec's ValidationError, taken apart. msgspec gives only a sentence
    (``Expected `int`, got `str` - at `$.points[0].x` ``); both the wire codec and the parameter
    files turn it into their own errors, so its format is read here and nowhere else — a change
    in msgspec's wording then breaks one function and its test, not two copies of a regex."""

    what: str                       # the sentence without its location, backticks kept
    path: tuple[str | int, ...]     # from the top: field names, list indices, "..." a map value
    in_key: bool = False            # the fault is in a map key at `path`, not in a value
    missing: str = ""               # "Object missing required field `x`": x
    unknown: str = ""               # "Object contains unknown field `x`": x
    expected: str = ""              # "Expected `int`, got `str`": int …
    got: str = ""                   # … and str
    not_finite: bool = False        # a `Finite` float got NaN or ±inf (its ge/le bounds failed)


_LOCATION = re.compile(r" - at (`key` in )?`\$([^`]*)`$")
_STEP = re.compile(r"\.([^.\[]+)|\[(\d+)\]|\[(\.\.\.)\]")
_EXPECTED = re.compile(r"^Expected `([^`]*)`(?:, got `([^`]*)`)?")
_MISSING = re.compile(r"^Object missing required field `([^`]*)`")
_UNKNOWN = re.compile(r"^Object contains unknown field `([^`]*)`")


_FMAX_TEXT = repr(sys.float_info.max)  # "1.7976931348623157e+308", as msgspec writes it


def validation_fault(exc: msgspec.ValidationError) -> ValidationFault:
    """What msgspec says went wrong, and where (see ValidationFault)."""
    text = str(exc)
    m = _LOCATION.search(text)
    what, path, in_key = text, (), False
    if m:
        what, in_key = text[:m.start()], bool(m.group(1))
        path = tuple(_step(*step) for step in _STEP.findall(m.group(2)))
    missing, unknown, expected = _MISSING.match(what), _UNKNOWN.match(what), _EXPECTED.match(what)
    return ValidationFault(
        what=what, path=path, in_key=in_key,
        missing=missing.group(1) if missing else "",
        unknown=unknown.group(1) if unknown else "",
        expected=expected.group(1) if expected else "",
        got=(expected.group(2) or "") if expected else "",
        # Finite's bounds are ±float max: only those say "not finite"; a type's own range
        # (msgspec.Meta(le=10.0)) keeps msgspec's words, which name the bound
        not_finite=what.startswith(("Expected `float` >=", "Expected `float` <="))
        and what.rstrip().endswith(_FMAX_TEXT))


def _step(name: str, index: str, any_key: str) -> str | int:
    return name or (int(index) if index else any_key)


def _translate(exc: Exception, type_name: str) -> DecodeError:
    text = str(exc)
    if isinstance(exc, msgspec.ValidationError):
        fault = validation_fault(exc)
        if fault.in_key:
            return NotMsgpack("not our wire format: a map key is not a string")
        where = "/".join(map(str, fault.path))
        if fault.missing:
            return MissingField(f"missing field '{fault.missing}' of "
                                f"{type_name if not where else 'this message'}",
                                f"{where}/{fault.missing}" if where else fault.missing)
        if fault.unknown:
            return UnknownField(f"unknown field '{fault.unknown}' for {type_name}", where)
        if fault.expected == "object":
            return NotAMap(f"expected a map for {type_name if not where else 'this field'}, "
                           f"got {fault.got}", where)
        if fault.not_finite:
            return NonFinite("expected a finite number", where)
        return WrongFieldType(fault.what.replace("`", ""), where)
    if "truncated" in text:
        return TruncatedPayload("payload ends in the middle of a msgpack value")
    if "trailing characters" in text:
        return NotMsgpack("trailing bytes after the msgpack value")
    if "invalid opcode" in text:
        return NotMsgpack("not msgpack: invalid or reserved type byte")
    if "depth" in text or "recursion" in text:
        return NotMsgpack("not msgpack: nesting too deep")
    return NotMsgpack(f"not msgpack: {text}")


_decoders: dict[type, Callable[[bytes], Any]] = {}
_generic = msgspec.msgpack.Decoder(dict)


_decoders_lock = threading.Lock()
# held by anyone else who makes msgspec build a Struct's type information (a JSON Schema:
# mrta_zenoh.flat_schema), for the reason struct_decoder gives
TYPE_INFO_LOCK = _decoders_lock


def struct_decoder(cls: type[Message]) -> Callable[[bytes], Any]:
    """The type's decoder, built once under a lock. Why the lock: msgspec (0.22) builds a
    Struct's type information on its first Decoder or convert, and two threads doing that at
    once crash the process (a segfault; Zenoh delivers samples on several threads, and a
    100-agent swarm hit it when many robots' first logs arrived together). Reproduced with 8
    threads making Decoder(cls) of a fresh Struct: 3 crashes in 3 runs, none with the lock
    (tests/process/test_codec_threads.py)."""
    dec = _decoders.get(cls)
    if dec is None:
        with _decoders_lock:
            dec = _decoders.get(cls)
            if dec is None:
                dec = _decoders[cls] = msgspec.msgpack.Decoder(cls).decode
    return dec


def decoder_for(encoding: str) -> tuple[str, Callable[[bytes], Any]]:
    """(type name, payload → message) for an encoding string: resolved once, used per sample.

    Unknown types decode to GenericMessage (any msgpack map), so generic tools still read them.
    """
    type_name = type_from_encoding(encoding)
    cls = message_class(type_name)
    raw = struct_decoder(cls) if cls is not None else _generic.decode
    errors = (msgspec.ValidationError, msgspec.DecodeError)

    def dec(payload: bytes) -> Any:
        if len(payload) > MAX_PAYLOAD_BYTES:
            raise PayloadTooLarge(f"payload of {len(payload)} bytes exceeds {MAX_PAYLOAD_BYTES}")
        try:
            value = raw(payload)
        except errors as exc:
            raise _translate(exc, type_name) from None
        except RecursionError:
            raise NotMsgpack("not msgpack: nesting too deep") from None
        return value if cls is not None else GenericMessage(type_name, value)

    return type_name, dec


def typed_decoder(encoding: str) -> tuple[str, Callable[[bytes], Any] | None]:
    """(type name, msgspec's own decode for its class) — None for a type this process does not
    know. For receive paths that inline decoder_for's checks; they must translate errors with
    `translate` and refuse payloads over MAX_PAYLOAD_BYTES themselves."""
    type_name = type_from_encoding(encoding)
    cls = message_class(type_name)
    return type_name, (struct_decoder(cls) if cls is not None else None)


DECODE_ERRORS = (msgspec.ValidationError, msgspec.DecodeError, RecursionError)


def translate(exc: Exception, type_name: str) -> DecodeError:
    """msgspec's error for a payload of `type_name` as one of our DecodeError classes."""
    if isinstance(exc, RecursionError):
        return NotMsgpack("not msgpack: nesting too deep")
    return _translate(exc, type_name)


def decode(type_name: str, payload: bytes) -> Message | GenericMessage:
    """Strictly decode a payload of the named type; unknown types become GenericMessage."""
    return decoder_for(encoding_for(type_name))[1](payload)
