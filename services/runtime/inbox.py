"""What a service has received and not handled yet, and what it owes an answer for; thread
safe (Zenoh's callbacks offer, the service's threads take).

``offer`` never waits: it drops a duplicate (same key and payload as one already taken),
refuses what is too large or does not fit its session's bounded FIFO (``intake.Intake``)
and queues the rest. A refused input is answered by an Error the reporter thread publishes
(OVERLOADED, TOO_LARGE), or counted as deferred if it is state the handler fetches again
(``Input.state``), or logged if its handler is an observer (recorder, viewer). ``take``
refuses the same way a message that waited too long: over ``max_wait_s``, or, once the
queue has stood (not emptied) for the handler's ``standing_s``, over its ``fresh_wait_s``.
Every received message is counted once as handled, dropped (by cause), duplicate or waiting.
"""

from __future__ import annotations

import logging
import threading
import time
import zlib
from collections import OrderedDict, deque

from findme_core.errors import BusError, FindmeError

from . import bus
from .handler import Handler, Input, Overloaded
from .intake import Intake, Item
from .sessions import SessionTable

log = logging.getLogger("findme.services")
MAX_REPORTS = 10000        # Errors waiting to be published; beyond, counted and logged
SEEN_PER_SESSION = 4096    # keys remembered per session to drop duplicates


def session_of(key: str) -> str:
    """The session part of ``findme/<session>/...`` ("" for any other key)."""
    parts = key.split("/", 2)
    return parts[1] if len(parts) > 2 and parts[0] == bus.ROOT else ""


class Inbox:
    """Queues, reports and counters of one service (see the module docstring)."""

    def __init__(self, handler: Handler, ident: str, session_depth: int = 32,
                 session_bytes: int = 64 << 20, total_bytes: int = 512 << 20,
                 seen_s: float = 180.0, max_wait_s: float | None = None):
        self.handler, self.ident, self.max_wait_s = handler, ident, max_wait_s
        self.cv = threading.Condition()
        self.intake = Intake(session_depth, session_bytes, total_bytes)
        self.seen = SessionTable(lambda s: OrderedDict(), idle_s=seen_s, max_sessions=100000)
        self.queries: deque = deque()    # (Input, zenoh.Query, session)
        self.query_sessions: dict[str, int] = {}   # queries waiting per session
        self.reports: deque = deque()
        self.frames_in = self.dropped = 0
        self.busy = 0            # worker threads handling something now
        self.next_tick = 0.0
        self.emptied = time.monotonic()    # when the queue was last seen empty
        self.more: dict[str, int] = {}     # counts by cause

    def count(self, what: str, n: int = 1) -> None:
        """(under ``cv``) add to a counter of the status report."""
        self.more[what] = self.more.get(what, 0) + n

    def bump(self, what: str, n: int = 1) -> None:
        with self.cv:
            self.count(what, n)

    def waited(self, seconds: float) -> None:
        """A message waited ``seconds`` in the queue before a worker took it (status:
        ``wait_us`` in all, ``wait_max_us``, ``waits``)."""
        us = int(1e6 * max(0.0, seconds))
        with self.cv:
            self.count("waits")
            self.count("wait_us", us)
            self.more["wait_max_us"] = max(self.more.get("wait_max_us", 0), us)

    def spent(self, wall_s: float, cpu_s: float) -> None:
        """A message was handled in ``wall_s`` s, ``cpu_s`` of them this thread's CPU
        (status: ``handle_us``, ``handle_cpu_us``)."""
        with self.cv:
            self.count("handle_us", int(1e6 * wall_s))
            self.count("handle_cpu_us", int(1e6 * cpu_s))

    def offer(self, i: int, key: str, payload: bytes, recovered: bool = False) -> bool:
        """Queue input ``i`` on ``key``, or answer it at once; returns whether it was queued."""
        inp = self.handler.inputs[i]
        session = session_of(key)
        digest = (len(payload), zlib.crc32(payload))
        with self.cv:
            self.frames_in += 1
            self.count("in_bytes", len(payload))
            seen = self.seen.get(session)
            had = seen.get(key)
            if had is not None and (had[0] == digest or (inp.once and had[1])):
                self.count("duplicates")
                return False
            if len(payload) > inp.max_bytes:
                self._refuse(inp, key, BusError(
                    f"{key} is {len(payload) / 1e6:.1f} MB, over the {inp.max_bytes / 1e6:.0f} MB "
                    f"limit of {self.handler.name}; it was not handled"), "too_large")
                return False
            now = time.monotonic()
            if not len(self.intake):
                self.emptied = now
            ok, superseded, why = self.intake.offer(
                Item(i, key, payload, session, recovered, now),
                latest=inp.depth if inp.policy == "latest" else None)
            for old in superseded:
                seen.pop(old.key, None)
                self._refuse(inp, old.key, Overloaded(
                    f"{old.key} was skipped: newer messages came (only the newest "
                    f"{inp.depth} are kept)"), "superseded")
            if not ok:
                self._refuse(inp, key, Overloaded(f"{key} was not handled by {self.handler.name}: "
                                                  f"{why}; send it again later"), "overloaded")
                return False
            seen[key] = (digest, False)
            seen.move_to_end(key)
            while len(seen) > SEEN_PER_SESSION:
                seen.popitem(last=False)
            if recovered:
                self.count("recovered")
            self.cv.notify_all()
            return True

    def offer_query(self, inp: Input, key: str, size: int, query) -> FindmeError | None:
        """(under ``cv``) Queue a query on ``key`` of ``size`` payload bytes, or the reason it
        is refused at once (counted; the caller answers the asker with it): over
        ``inp.max_bytes``, or ``inp.depth`` of its session's queries already waiting (one
        client's flood of queries must not hold up everyone's messages: queries go first)."""
        self.frames_in += 1
        session = session_of(key)
        if size > inp.max_bytes:
            self.count("queries_too_large")
            return BusError(f"the query on {key} is {size / 1e3:.0f} kB, over the "
                            f"{inp.max_bytes / 1e3:.0f} kB limit of {self.handler.name}")
        waiting = self.query_sessions.get(session, 0)
        if waiting >= inp.depth:
            self.count("queries_overloaded")
            return Overloaded(f"{waiting} queries of session {session!r} already wait at "
                              f"{self.handler.name}: ask again when they are answered")
        self.query_sessions[session] = waiting + 1
        self.queries.append((inp, query, session))
        self.cv.notify_all()
        return None

    def query_taken(self, session: str) -> None:
        """(under ``cv``) One query of ``session`` left the queue."""
        n = self.query_sessions.pop(session, 0) - 1
        if n > 0:
            self.query_sessions[session] = n

    def _refuse(self, inp: Input, key: str, exc: FindmeError, cause: str) -> None:
        """(under ``cv``) An input not handled: answered if it must be, always counted."""
        self.dropped += 1
        if inp.state:
            self.count("deferred")   # state the handler fetches again when it needs it
            return
        self.count(cause)
        if not self.handler.report_overload or inp.type is None:   # observers: recorder, viewer
            log.error("%s: %s", self.ident, exc)
            return
        if len(self.reports) >= MAX_REPORTS:
            self.count("unreported")
            log.error("%s: not reported (too many reports waiting): %s", self.ident, exc)
            return
        self.reports.append((key, exc))
        self.cv.notify_all()

    def take(self) -> Item | None:
        """(under ``cv``) The next item to handle, round-robin between sessions; one that
        waited more than ``max_wait_s`` is answered OVERLOADED instead (a result that late
        is of no use to a phone; a queue that deep says the service cannot keep up), and
        under a standing queue one that waited more than the handler's ``fresh_wait_s``."""
        while True:
            item, now = self.intake.pop(), time.monotonic()
            standing = now - self.emptied      # the queue stood until this item left it
            if not len(self.intake):
                self.emptied = now
            if item is None or self.max_wait_s is None:
                return item
            waited, limit, why = now - item.t, self.max_wait_s, ""
            fresh = self.handler.fresh_wait_s
            if fresh is not None and standing > self.handler.standing_s:
                limit = min(limit, fresh)
                why = f", which has not emptied for {standing:.0f} s (it cannot keep up)"
            if waited <= limit:
                return item
            self.seen.get(item.session).pop(item.key, None)   # sending it again is no duplicate
            self._refuse(self.handler.inputs[item.input], item.key, Overloaded(
                f"{item.key} waited {waited:.1f} s in {self.handler.name}'s queue{why} (at "
                f"most {limit:g} s): not handled; send it again later"),
                "shed" if why else "expired")

    def next_work(self, done: bool, stop: threading.Event, tick_s: float | None,
                  idle: threading.Event):
        """What a worker thread does next (``done``: it finished one): a query first, a
        tick when due, then a message, round-robin between sessions; (None, None) once
        ``stop`` is set. Sets ``idle`` when nothing waits and no worker is busy."""
        with self.cv:
            self.busy -= done
            while not stop.is_set():
                now = time.monotonic()
                if self.queries:
                    kind, item = "query", self.queries.popleft()
                    self.query_taken(item[2])
                    item = item[:2]
                elif tick_s is not None and now >= self.next_tick:
                    self.next_tick = now + tick_s
                    kind, item = "tick", now
                else:
                    item = self.take()
                    kind = "msg" if item is not None else None
                if kind is not None:
                    self.busy += 1
                    return kind, item
                if not self.busy:
                    idle.set()
                self.cv.wait(0.5 if tick_s is None else max(0.0, min(0.5, self.next_tick - now)))
        return None, None

    def session_waiting(self, session: str) -> int:
        """Messages of ``session`` received and not taken yet."""
        with self.cv:
            return self.intake.waiting(session)

    def knows(self, key: str) -> bool:
        """Whether ``key`` was taken (queued or handled) here lately."""
        with self.cv:
            return key in self.seen.get(session_of(key))

    def handled(self, key: str) -> None:
        """``key`` was handled without error: for a ``once`` input, later copies are dropped."""
        with self.cv:
            seen = self.seen.get(session_of(key))
            if key in seen:
                seen[key] = (seen[key][0], True)

    def forget(self, key: str) -> None:
        with self.cv:
            self.seen.get(session_of(key)).pop(key, None)

    def waiting(self) -> int:
        """(under ``cv``) queries and messages waiting."""
        return len(self.intake) + len(self.queries)
