"""What a service's pure logic is: a ``Handler`` declares its inputs and queries and turns one
decoded message into ``Output``s, knowing nothing about Zenoh, so tests drive it directly
(``runtime.Service`` runs it on a bus). Also the mapping from errors to the ``Error``
message a service publishes on ``findme/<session>/error``.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import schemas
from findme_core.errors import (BusError, CameraError, FindmeError, GeometryError,
                                HypothesisError, ImageError, InputError, MotionError,
                                SchemaError)

from . import authority, bus


@dataclass(frozen=True)
class Input:
    """One subscription or queryable of a handler.

    key: key expression, e.g. ``findme/*/frame/*``; type: expected message class, or None
    for raw payloads of any type (``on_message`` gets the bytes undecoded: recorder, viewer);
    policy: "all" (never dropped) or "latest" (newest ``depth`` kept, drops counted).
    """

    key: str
    type: type
    policy: str = "all"
    depth: int = 64


@dataclass(frozen=True)
class Output:
    """A message to publish on ``key``; ``cache`` keeps it for late joiners' queries."""

    key: str
    msg: object
    cache: bool = True


class UnknownSession(FindmeError):
    """A message refers to a session this service has never seen."""


class Handler:
    """Base of every service's pure logic. Subclasses set the class attributes and override
    ``on_message`` / ``on_query``; they may raise FindmeError for bad input."""

    name = "service"
    inputs: tuple[Input, ...] = ()
    queries: tuple[Input, ...] = ()
    cache_keys: tuple[str, ...] = ()
    shard = False
    #: handle everything already received before stopping (Service.stop waits for idle)
    drain_on_stop = False
    #: fetch(key) -> payload bytes or None: ask the bus for a message this handler missed
    #: (set by Service; tests set a dict lookup). None = no way to ask.
    fetch = None

    def need(self, key: str, cls):
        """A message this handler depends on but has not seen, fetched from the bus.

        Raises:
            HypothesisError: nobody on the bus has it.
        """
        data = self.fetch(key) if self.fetch else None
        if data is None:
            raise HypothesisError(f"{key} is not known (not received and not on the bus)")
        msg = schemas.decode(cls, data)
        authority.check(key, msg)
        return msg

    def on_message(self, key: str, msg) -> list[Output]:
        return []

    def on_query(self, key: str, msg):
        raise NotImplementedError

    def shard_key(self, key: str, msg) -> str:
        """What decides which instance handles a message (default: the whole key)."""
        return key

    def counters(self) -> dict[str, int]:
        """Service-specific counters for the status report."""
        return {}

    def close(self) -> None:
        """Called once by Service.stop after the worker has stopped (release files etc.)."""


CODES = [  # most specific first
    (schemas.WrongTypeError, schemas.ErrorCode.ERROR_CODE_WRONG_TYPE),
    (SchemaError, schemas.ErrorCode.ERROR_CODE_MALFORMED),
    (authority.KeyAuthorityError, schemas.ErrorCode.ERROR_CODE_FORBIDDEN),
    (ImageError, schemas.ErrorCode.ERROR_CODE_BAD_IMAGE),
    (CameraError, schemas.ErrorCode.ERROR_CODE_BAD_CAMERA),
    (HypothesisError, schemas.ErrorCode.ERROR_CODE_NO_SUCH_HYPOTHESIS),
    (UnknownSession, schemas.ErrorCode.ERROR_CODE_UNKNOWN_SESSION),
    (GeometryError, schemas.ErrorCode.ERROR_CODE_DEGENERATE),
    (MotionError, schemas.ErrorCode.ERROR_CODE_DEGENERATE),
    (InputError, schemas.ErrorCode.ERROR_CODE_MALFORMED),
    (BusError, schemas.ErrorCode.ERROR_CODE_TOO_LARGE),
]


def error_code(exc: BaseException) -> int:
    for cls, code in CODES:
        if isinstance(exc, cls):
            return code
    return schemas.ErrorCode.ERROR_CODE_INTERNAL


def error_message(key: str, exc: BaseException, service: str) -> tuple[str, object]:
    """(error key, Error message) reporting ``exc`` raised while handling ``key``."""
    try:
        session = bus.parse_key(key).session
        ekey = bus.key(session, "error")
    except BusError:
        session, ekey = "", f"{bus.ROOT}/@errors"
    text = str(exc) if isinstance(exc, FindmeError) else f"internal error: {type(exc).__name__}: {exc}"
    return ekey, schemas.Error(session=session, key=str(key), code=error_code(exc),
                               message=text.splitlines()[0][:500] if text else type(exc).__name__,
                               time_ns=time.time_ns(), service=service)
