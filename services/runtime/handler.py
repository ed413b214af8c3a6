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
                                HypothesisError, ImageError, InputError, MotionError, SchemaError)

from . import authority, bus


@dataclass(frozen=True)
class Input:
    """One subscription or queryable of a handler.

    key: key expression, e.g. ``findme/*/frame/*``; type: expected message class, or None
    for raw payloads of any type (``on_message`` gets the bytes undecoded: recorder, viewer);
    policy: "all" (queued per session; a full queue answers OVERLOADED) or "latest" (the
    newest ``depth`` of a session kept; each superseded one is answered OVERLOADED).
    answers: templates of the keys whose presence on the bus shows that the input
    ``findme/<session>/<kind>/<n>`` was handled, e.g. ``"findme/{session}/hypotheses/{n}"``
    (the last part must be ``{n}``). An input with answers is one the service must answer
    (its result, or an Error): a restarted or new instance recovers unanswered ones from the
    bus.
    state: the input is state the handler fetches again when it needs it (``need``), e.g.
    the frames the mapper also gets: when queues are full it is skipped and counted as
    deferred, not answered with an error. Any other input that cannot be queued is answered
    by an Error (OVERLOADED, TOO_LARGE), or only logged and counted if the handler does not
    ``report_overload`` (the recorder).
    once: a key is handled once: a later message on it is dropped as a duplicate even if
    its payload differs (a result recomputed elsewhere, e.g. by an instance cut off the
    network that comes back); without it only identical payloads are (a user may change a
    selection). Only while the key is remembered (``Service(seen_s=...)``, 180 s).
    max_bytes: larger payloads are refused with TOO_LARGE before they are queued.
    For a query (``Handler.queries``) ``depth`` is how many of a session's queries may wait
    (more are answered OVERLOADED at once) and ``max_bytes`` bounds its payload the same way.
    """

    key: str
    type: type
    policy: str = "all"
    depth: int = 64
    answers: tuple[str, ...] = ()
    state: bool = False
    once: bool = False
    max_bytes: int = bus.MAX_MESSAGE_BYTES


@dataclass(frozen=True)
class Output:
    """A message to publish on ``key``; ``cache`` keeps it for late joiners' queries."""

    key: str
    msg: object
    cache: bool = True


class UnknownSession(FindmeError):
    """A message refers to a session this service has never seen."""


class Overloaded(FindmeError):
    """A message was not handled because a queue was full or a newer one superseded it."""


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
    #: fetch_all(key expression) -> [(key, payload)]: every message the bus still holds
    #: for a key expression (set by Service). None = no way to ask.
    fetch_all = None
    #: served in its own process (``findme serve``), run at this lower CPU priority
    #: (``os.nice``): background work (the mapper's floor plans) yields to the phones' poses
    nice = 0
    #: served in its own process, off the path from a photo to its pose (the store, the
    #: recorder, the floor plans): run under Linux's SCHED_BATCH policy (applied by
    #: ``findme serve`` before the bus starts its threads), so that the message that wakes
    #: it waits for the running photo's scheduler slice instead of preempting it
    background = False
    #: backlog(session) -> messages of that session received and not handled yet (set by
    #: Service). None (a test driving the handler) = nothing is known to be waiting.
    backlog = None
    #: worker threads: > 1 only for a handler whose ``on_message`` may run concurrently (no
    #: shared state; OpenCV and numpy release the GIL): a second photo is not held up by a
    #: large one in progress
    threads = 1
    #: messages a session may have waiting (``Service(fifo_depth=...)`` overrides)
    queue_depth = 32
    #: seconds a message may wait in the queue before it is answered OVERLOADED (None: the
    #: service's ``max_wait_s``, ``--max-wait``); longer for background work whose results
    #: may come late (the mapper)
    max_wait_s: float | None = None
    #: under a standing queue (one that has not emptied for ``standing_s`` seconds: the
    #: service cannot keep up), a message that waited longer than this is answered
    #: OVERLOADED (None: only ``max_wait_s``). A queue that absorbs a burst still holds
    #: messages up to ``max_wait_s``; one that stands serves fresh ones, and its oldest are
    #: refused at once instead of after ``max_wait_s`` (the "controlled delay" of Maurer,
    #: "Fail at Scale", ACM Queue 13(8) 2015, after CoDel, RFC 8289). For the photos'
    #: first stage: a pose 10 s late is of no use to a phone that moved on
    fresh_wait_s: float | None = None
    standing_s: float = 5.0
    #: call ``tick`` about every this many seconds (None: never), on the worker thread
    tick_s: float | None = None
    #: ``on_message`` is O(1) and never blocks: run it in Zenoh's callback, unqueued (store)
    inline = False
    #: publish an Error for each input it could not queue (False: log and count only).
    #: Raw inputs (``type`` None: the recorder, the viewer) are never reported: observers
    report_overload = True

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

    def check_input(self, key: str, msg) -> None:
        """Raise InputError naming ``key`` unless ``msg`` is of a type one of ``inputs``
        declares. The bus never delivers another; a caller driving the handler directly
        (a test, a bench, a replay) is told, before any state is made for it."""
        if not any(i.type is not None and isinstance(msg, i.type) for i in self.inputs):
            raise InputError(f"the {self.name} service takes no {type(msg).__name__} ({key})")

    def on_message(self, key: str, msg) -> list[Output]:
        return []

    def on_query(self, key: str, msg):
        raise NotImplementedError

    def cached(self, key_expr: str, parameters) -> list[tuple[str, bytes]]:
        """Messages this handler holds for ``get`` queries on its ``cache_keys``, besides
        the outputs the Service caches (the store holds everything recent)."""
        return []

    def tick(self, now: float) -> list[Output]:
        """Called about every ``tick_s`` seconds (``now``: monotonic seconds) for work that
        waits on time, e.g. giving up on a photo that never comes."""
        return []

    def peers_changed(self) -> None:
        """(sharded handlers) An instance of this service came or went, so the sessions this
        one owns changed: drop state that another instance may have moved on meanwhile."""

    def shard_key(self, key: str, msg) -> str:
        """What decides which instance handles a message (default: the whole key). Called
        with ``msg=None`` when the message is not decoded yet: depend on the key only."""
        return key

    def counters(self) -> dict[str, int]:
        """Service-specific counters for the status report."""
        return {}

    def close(self) -> None:
        """Called once by Service.stop after the worker has stopped (release files etc.)."""


CODES = [  # most specific first
    (schemas.WrongTypeError, schemas.ErrorCode.ERROR_CODE_WRONG_TYPE),
    (SchemaError, schemas.ErrorCode.ERROR_CODE_MALFORMED),
    (Overloaded, schemas.ErrorCode.ERROR_CODE_OVERLOADED),
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
