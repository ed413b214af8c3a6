"""A polite sender: at most ``window`` frames of a session on their way at once.

The services answer a session's burst beyond their queue with OVERLOADED (they never block
the bus); our own senders (capture, ``findme run`` on a folder of photos) instead wait for
answers, so a long series is paced by the slowest stage, not refused. A frame is answered
by its hypotheses or by an Error naming it. A phone app of someone else's making may send
as it likes: it gets OVERLOADED answers when it outruns the services.
"""

from __future__ import annotations

import logging
import threading

import zenoh

import schemas

from . import bus

log = logging.getLogger("findme.services")


class Pacer:
    """Counts the frames of ``session`` sent and answered; ``wait_room`` blocks while
    ``window`` are unanswered (for at most ``stall_s`` without any answer, then goes on and
    says so)."""

    def __init__(self, session: zenoh.Session, session_id: str, window: int = 8,
                 stall_s: float = 30.0):
        if window < 1:
            raise ValueError(f"window must be at least 1, got {window}")
        self.window, self.stall_s = window, stall_s
        self._cv = threading.Condition()
        self._open: set[int] = set()
        self._answered: set[int] = set()
        self._subs = [session.declare_subscriber(bus.key(session_id, "hypotheses", "*"), self._on_result),
                      session.declare_subscriber(bus.key(session_id, "error"), self._on_error)]

    def _done(self, n: int) -> None:
        with self._cv:
            self._answered.add(n)
            self._open.discard(n)
            self._cv.notify_all()

    def _on_result(self, sample: zenoh.Sample) -> None:
        try:
            self._done(bus.parse_key(str(sample.key_expr)).index())
        except Exception:  # noqa: BLE001 - a foreign key: not an answer
            pass

    def _on_error(self, sample: zenoh.Sample) -> None:
        try:
            err = schemas.decode(schemas.Error, sample.payload.to_bytes())
            k = bus.parse_key(err.key)
            if k.kind == "frame":
                self._done(k.index())
        except Exception:  # noqa: BLE001 - a foreign or malformed error: not an answer
            pass

    def sent(self, n: int) -> None:
        with self._cv:
            if n not in self._answered:
                self._open.add(n)

    def wait_room(self) -> None:
        with self._cv:
            while len(self._open) >= self.window:
                before = len(self._answered)
                if not self._cv.wait_for(lambda: len(self._answered) > before, self.stall_s):
                    log.warning("no answer to frames %s for %.0f s: sending on",
                                sorted(self._open), self.stall_s)
                    self._open.clear()

    def close(self) -> None:
        for s in self._subs:
            try:
                s.undeclare()
            except zenoh.ZError:
                pass  # the session may already be closed
