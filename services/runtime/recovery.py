"""Which inputs of a handler are unanswered on the bus: what a service that was down (or a
new instance, or one whose peer died) must still handle.

An input ``findme/<s>/<kind>/<n>`` with ``Input.answers`` is answered when the store holds
one of its answer keys (e.g. ``findme/<s>/hypotheses/<n>``) or an Error from this service
(``Error.service`` "<name>/<instance>") about that key. Everything else the store holds on
the input's key expression, within its window, is unanswered. ``Service.sweep`` then
handles those it owns and has not seen, fetched from the bus; handlers downstream drop
what they have already handled (same key, same payload), so a race between two instances
costs work, not a duplicate result.
"""

from __future__ import annotations

import logging
import time

import zenoh

import schemas
from findme_core.errors import FindmeError

from . import bus
from .handler import Handler, Input

log = logging.getLogger("findme.services")


def _selector(template: str) -> str:
    return template.format(session="*", n="*")


def listing(session: zenoh.Session, key_expr: str, timeout: float = 5.0,
            since_ns: int = 0, cancel: zenoh.CancellationToken | None = None) -> dict[str, int]:
    """key -> receive time (ns) of what the store(s) hold on ``key_expr`` (received at or
    after ``since_ns``)."""
    out: dict[str, int] = {}
    params = f"meta;since={since_ns}" if since_ns else "meta"
    for k, meta in bus.get_all(session, f"{key_expr}?{params}", timeout, cancel=cancel):
        try:
            t = int(meta.split(b" ", 1)[0])
        except ValueError:
            continue  # a cache that is not a store answered with a payload: not a listing
        out[k] = max(t, out.get(k, 0))
    return out


def _identity(key: str) -> tuple[str, str] | None:
    """(session, last part) of a session key, the photo an answer or input is about."""
    try:
        k = bus.parse_key(key)
    except Exception:  # noqa: BLE001 - foreign key: not ours to answer
        return None
    return (k.session, k.parts[-1]) if k.parts else None


def answered(session: zenoh.Session, handler: Handler, inp: Input,
             errors: list[tuple[str, bytes]], timeout: float = 5.0,
             since_ns: int = 0, cancel: zenoh.CancellationToken | None = None
             ) -> set[tuple[str, str]]:
    """(session, n) of every input on ``inp`` that has an answer (or an Error of ours)."""
    done: set[tuple[str, str]] = set()
    for template in inp.answers:
        if not template.endswith("/{n}"):
            raise ValueError(f"answer template {template!r} must end with /{{n}}")
        for k in listing(session, _selector(template), timeout, since_ns, cancel):
            ident = _identity(k)
            if ident is not None:
                done.add(ident)
    want = zenoh.KeyExpr(inp.key)
    for _, payload in errors:
        try:
            err = schemas.decode(schemas.Error, payload)
        except Exception:  # noqa: BLE001 - a malformed error is no answer of ours
            continue
        if err.service.split("/")[0] != handler.name or not err.key:
            continue
        try:
            if not want.intersects(zenoh.KeyExpr(err.key)):
                continue
        except zenoh.ZError:
            continue
        ident = _identity(err.key)
        if ident is not None:
            done.add(ident)
    return done


def unanswered(session: zenoh.Session, handler: Handler, grace_ns: int, now_ns: int,
               timeout: float = 5.0, since_ns: int = 0,
               cancel: zenoh.CancellationToken | None = None) -> list[tuple[int, str, int]]:
    """(input index, key, receive time) of every input the store holds for ``handler``
    without an answer, received at least ``grace_ns`` before ``now_ns`` (and at or after
    ``since_ns``: answers come after their inputs, so both are asked from then); by session,
    then photo number (the order a session's photos were taken, which the bus does not
    keep). ``cancel``: ends every wait on the bus at once (``Service.stop``)."""
    todo = []
    if not any(inp.answers for inp in handler.inputs):
        return todo
    errors = bus.get_all(session, f"findme/*/error?since={since_ns}" if since_ns else
                         "findme/*/error", timeout, cancel=cancel)
    for i, inp in enumerate(handler.inputs):
        if not inp.answers:
            continue
        held = listing(session, inp.key, timeout, since_ns, cancel)
        if not held:
            continue
        done = answered(session, handler, inp, errors, timeout, since_ns, cancel)
        for k, t in held.items():
            if now_ns - t >= grace_ns and _identity(k) not in done:
                todo.append((i, k, t))
    def order(x):
        session, n = _identity(x[1]) or ("", "")
        return (session, int(n) if n.isdigit() else -1, x[2])
    todo.sort(key=order)
    return todo


class Sweeper:
    """The recovery thread of a ``service.Service``: the first sweep (at start) and one
    after a change of instances look at the whole window the bus holds; periodic ones
    (every ``sweep_s``) at what came since the last, with a margin: every input is looked
    at, none twice in full."""

    MARGIN_S = 5.0

    def __init__(self, service):
        self.svc = service

    def run(self) -> None:
        svc = self.svc
        grace, done_to = 0.0, 0   # at start nothing is in flight to this instance yet
        while True:
            whole = svc._sweep_now.wait(svc.sweep_s) or not done_to
            if svc._stop.is_set():
                return
            svc._sweep_now.clear()
            now = time.time_ns()
            since = 0 if whole else max(0, done_to - int(1e9 * (svc.grace_s + self.MARGIN_S)))
            try:
                self.sweep(grace, since)
                done_to = now - int(grace * 1e9)
            except (zenoh.ZError, FindmeError) as e:
                if svc._stop.is_set():
                    return   # the stop cancelled the sweep's queries
                log.warning("%s: recovery sweep failed: %s", svc.ident, e)
            grace = svc.grace_s

    def sweep(self, grace_s: float = 0.0, since_ns: int = 0) -> int:
        """Fetch and queue every unanswered input the bus holds (received since
        ``since_ns``, at least ``grace_s`` ago) that is this instance's and not seen here;
        returns how many."""
        svc = self.svc
        todo = unanswered(svc.session, svc.handler, int(grace_s * 1e9), time.time_ns(),
                          since_ns=since_ns, cancel=svc._cancel)
        n = 0
        for i, key, _ in todo:
            if svc._stop.is_set():
                break
            if (svc.handler.shard and not svc._owns(key)) or svc.inbox.knows(key):
                continue
            data = svc.fetch(key)
            if data is not None and svc.offer(i, key, data, recovered=True):
                n += 1
        svc.inbox.bump("sweeps")
        if n:
            log.info("%s: recovered %d unanswered inputs from the bus", svc.ident, n)
        return n
