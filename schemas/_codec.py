"""encode / decode of bus messages with a type guard and structural validation."""

from __future__ import annotations

from typing import Protocol, TypeVar, Union

from google.protobuf.message import DecodeError, Message

from findme_core.errors import SchemaError

from ._validate import VALIDATORS
from .v1 import common_pb2, frame_pb2, hypotheses_pb2, measure_pb2, motion_pb2, scene_pb2
from .v1 import plan_pb2, selection_pb2, status_pb2

M = TypeVar("M", bound=Message)


class SupportsToBytes(Protocol):
    """A payload object such as ``zenoh.ZBytes``."""

    def to_bytes(self) -> bytes: ...


Payload = Union[bytes, bytearray, memoryview, SupportsToBytes]


class WrongTypeError(SchemaError):
    """The payload is a valid Find Me message, but of another type than expected
    (an ``ERROR_CODE_WRONG_TYPE``; any other SchemaError is ``ERROR_CODE_MALFORMED``)."""


#: Full name -> class of every top-level bus message.
MESSAGE_TYPES: dict[str, type[Message]] = {
    cls.DESCRIPTOR.full_name: cls for cls in (
        frame_pb2.Frame,
        hypotheses_pb2.HypothesisSet,
        selection_pb2.Selection,
        scene_pb2.Scene,
        measure_pb2.MeasureRequest,
        measure_pb2.MeasureReply,
        motion_pb2.Motion,
        motion_pb2.Pose,
        motion_pb2.Trajectory,
        plan_pb2.Plan,
        status_pb2.Error,
        status_pb2.ServiceStatus,
    )
}
if set(MESSAGE_TYPES) != set(VALIDATORS):  # a type added without its checks
    raise ImportError(f"schemas: no validator for {sorted(set(MESSAGE_TYPES) ^ set(VALIDATORS))}")

_MAX_PROBLEMS = 5


def _full_name(cls: type[Message]) -> str:
    name = getattr(getattr(cls, "DESCRIPTOR", None), "full_name", None)
    if name not in MESSAGE_TYPES or MESSAGE_TYPES[name] is not cls:
        raise TypeError(f"{cls!r} is not a Find Me bus message type; expected one of "
                        f"{', '.join(sorted(MESSAGE_TYPES))}")
    return name


def _as_bytes(data: Payload, expected: str) -> bytes:
    if isinstance(data, bytes):
        return data
    if isinstance(data, (bytearray, memoryview)):
        return bytes(data)
    to_bytes = getattr(data, "to_bytes", None)
    if callable(to_bytes) and not isinstance(data, (int, str)):
        raw = to_bytes()
        if isinstance(raw, (bytes, bytearray)):
            return bytes(raw)
    raise SchemaError(f"cannot decode {expected}: the payload must be bytes, "
                      f"got {type(data).__name__}")


def _raise_problems(verb: str, name: str, problems: list[str]) -> None:
    if problems:
        shown = "; ".join(problems[:_MAX_PROBLEMS])
        more = len(problems) - _MAX_PROBLEMS
        if more > 0:
            shown += f"; and {more} more"
        raise SchemaError(f"{verb} {name}: {shown}")


def _problems(msg: Message, name: str) -> list[str]:
    tag = msg.schema  # type: ignore[attr-defined]
    problems = [] if tag == name else [f"schema is {tag!r}, expected {name!r}"]
    return problems + VALIDATORS[name](msg)


def validate(msg: Message) -> None:
    """Raise SchemaError listing what is wrong with a bus message (its schema tag included)."""
    name = _full_name(type(msg))
    _raise_problems("invalid", name, _problems(msg, name))


def encode(msg: Message, *, check: bool = True) -> bytes:
    """Serialize a bus message (deterministically: maps in key order).

    Sets ``msg.schema`` to the message's full name when it is empty. With ``check``
    (the default) the message is validated first, so nothing invalid is published.

    Raises:
        TypeError: ``msg`` is not a Find Me bus message.
        SchemaError: ``msg.schema`` names another type, or (with ``check``) a field is invalid.
    """
    name = _full_name(type(msg))
    if not msg.schema:  # type: ignore[attr-defined]
        msg.schema = name  # type: ignore[attr-defined]
    if check:
        _raise_problems("cannot encode", name, _problems(msg, name))
    elif msg.schema != name:  # type: ignore[attr-defined]
        raise SchemaError(f"cannot encode {name}: schema is {msg.schema!r}")  # type: ignore[attr-defined]
    return msg.SerializeToString(deterministic=True)


def _tag_problem(expected: str, tag: str, size: int) -> SchemaError:
    if not tag:
        return SchemaError(
            f"cannot decode {expected}: the {size}-byte payload has no schema tag (field 1), "
            "so it is not a Find Me message (or its producer did not set `schema`)")
    if tag in MESSAGE_TYPES:
        return WrongTypeError(f"expected {expected}, got a {tag} message")
    shown = tag if len(tag) <= 60 else tag[:57] + "..."
    return SchemaError(f"cannot decode {expected}: the payload's schema tag {shown!r} is not "
                       f"a known message type (this build knows findme.v1)")


def schema_of(data: Payload) -> str:
    """The schema tag (full message name) of a payload, "" when it has none.

    Raises:
        SchemaError: the payload is empty or not protobuf.
    """
    raw = _as_bytes(data, "a Find Me message")
    if not raw:
        raise SchemaError("cannot decode a Find Me message: empty payload")
    try:
        return common_pb2.Envelope.FromString(raw).schema
    except DecodeError as exc:
        raise SchemaError(f"cannot decode a Find Me message: the {len(raw)}-byte payload is "
                          f"not valid protobuf ({exc})") from None


def decode(cls: type[M], data: Payload, *, check: bool = True) -> M:
    """Parse a payload as ``cls``, checking its schema tag and (with ``check``) its fields.

    Raises:
        TypeError: ``cls`` is not a Find Me bus message type.
        WrongTypeError: the payload is a Find Me message of another type.
        SchemaError: the payload is empty, not protobuf (truncated, garbage), has no or an
            unknown schema tag, or (with ``check``) a field is invalid. The message names
            ``cls``'s full name and the problem.
    """
    name = _full_name(cls)
    raw = _as_bytes(data, name)
    if not raw:
        raise SchemaError(f"cannot decode {name}: empty payload")
    try:
        msg = cls.FromString(raw)
    except DecodeError as exc:
        try:
            tag = common_pb2.Envelope.FromString(raw).schema
        except DecodeError:
            tag = ""
        if tag in MESSAGE_TYPES and tag != name:
            raise WrongTypeError(f"expected {name}, got a {tag} message") from None
        raise SchemaError(f"cannot decode {name}: the {len(raw)}-byte payload is not valid "
                          f"protobuf (truncated or garbage: {exc})") from None
    tag = msg.schema  # type: ignore[attr-defined]
    if tag != name:
        raise _tag_problem(name, tag, len(raw))
    if check:
        _raise_problems("invalid", name, VALIDATORS[name](msg))
    return msg


def decode_any(data: Payload, *, check: bool = True) -> Message:
    """Parse a payload as whatever Find Me message its schema tag names.

    Raises:
        SchemaError: as ``decode``; also when the tag is missing or unknown.
    """
    raw = _as_bytes(data, "a Find Me message")
    tag = schema_of(raw)
    cls = MESSAGE_TYPES.get(tag)
    if cls is None:
        raise _tag_problem("a Find Me message", tag, len(raw))
    return decode(cls, raw, check=check)
