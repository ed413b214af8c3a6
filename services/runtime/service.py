"""Runs a pure handler on the bus: decode, handle, encode, publish; errors, counters,
liveliness, status, a latched cache of outputs, sharding among instances, recovery of what
was missed, shutdown.

A *handler* (``handler.Handler``) knows nothing about Zenoh: it declares its inputs and
queries and turns one decoded message into outputs, so tests drive it directly. ``Service``
wires it to a session. Delivery (issue 10; README "Delivery"):

* Zenoh's callback never waits: it checks the size, the owner (sharding) and duplicates
  (same key, same payload), and queues the message in its session's bounded FIFO
  (``intake.Intake``, served round-robin between sessions). A message that does not fit is
  answered at once by an Error (OVERLOADED, TOO_LARGE) on ``findme/<session>/error``,
  published by a reporter thread (``inbox.Inbox``); an input the handler can fetch again
  later (``Input.state``) is skipped and counted as deferred. A callback that blocked would stall the
  router's queue to this process until the router closes the link ("Unable to push non
  droppable network message ... Closing transport!") and every message on it is lost.
* one worker thread (``Handler.threads`` for a handler that is safe to call from several:
  hypotheses) handles queries first, then messages; ``tick`` when the handler asks.
* any exception while handling becomes an Error and a log line; the service goes on.
* outputs marked ``cache`` are kept (bounded) and served to ``get`` on ``cache_keys``.
* with ``shard`` set, instances of a service split the work by rendezvous hashing over the
  live instances (``peers.Peers``: a liveliness subscriber with history).
* recovery: at start, when an instance joins or leaves, and every ``sweep_s`` seconds, the
  inputs the bus still holds (the store's window, the producers' caches) that have no
  answer yet and are this instance's are fetched and handled (``recovery``).
"""

from __future__ import annotations

import logging
import threading
import time
import traceback
import uuid
from dataclasses import dataclass, field

import zenoh

import schemas
from findme_core.errors import FindmeError, SchemaError

from . import bus, recovery
from .cache import OutputCache, is_exact
from .handler import Handler, Input, Output, error_message
from .inbox import Inbox
from .peers import Peers, owner

log = logging.getLogger("findme.services")


@dataclass
class Counters:
    """The totals of a status report (kept for callers of ``Service.counters``)."""

    frames_in: int = 0
    results_out: int = 0
    errors: int = 0
    dropped: int = 0


class Service:
    """A handler running on a Zenoh session (see the module docstring).

    fifo_depth / session_bytes: messages / bytes a session may have waiting (default depth:
    the handler's ``queue_depth``); max_wait_s: a message that waited longer is answered
    OVERLOADED instead of handled (None: no limit; observers such as the recorder have none);
    queue_bytes: bytes all sessions may have waiting; sweep_s: seconds between recovery
    sweeps (None: none, not even at start); grace_s: a periodic sweep leaves inputs younger
    than this to their live delivery.
    """

    def __init__(self, handler: Handler, session: zenoh.Session, instance: str | None = None,
                 fifo_depth: int | None = None, cache_bytes: int = 64 * 1024 * 1024,
                 max_message_bytes: int = bus.MAX_MESSAGE_BYTES, session_bytes: int = 64 << 20,
                 queue_bytes: int = 512 << 20, sweep_s: float | None = 10.0, grace_s: float = 2.0,
                 seen_s: float = 180.0, max_wait_s: float | None = 10.0):
        self.handler, self.session = handler, session
        self.instance = instance or uuid.uuid4().hex[:8]
        self.ident = f"{handler.name}/{self.instance}"
        self.inbox = Inbox(handler, self.ident, fifo_depth or handler.queue_depth, session_bytes,
                           queue_bytes, seen_s, max_wait_s if handler.report_overload else None)
        self._cv = self.inbox.cv
        self.results_out = self.errors = 0
        self.started_ns = time.time_ns()
        self.max_message_bytes = max_message_bytes
        self.sweep_s, self.grace_s = sweep_s, grace_s
        self._stop = threading.Event()
        self._sweep_now = threading.Event()
        self._cache = OutputCache(cache_bytes)
        self._peers: Peers | None = None
        self._decls: list = []
        self._threads: list[threading.Thread] = []
        self._next_tick = 0.0
        self._busy = 0                  # worker threads handling something now
        if handler.threads > 1 and handler.tick_s is not None:
            raise ValueError(f"{handler.name}: a handler with ticks has one worker thread")
        self.idle = threading.Event()   # set when nothing is queued or being handled
        self.idle.set()
        handler.fetch = self.fetch
        handler.fetch_all = self.fetch_all

    @property
    def counters(self) -> Counters:
        with self._cv:
            return Counters(self.inbox.frames_in, self.results_out, self.errors, self.inbox.dropped)

    # ------------------------------------------------------------------ lifecycle
    def start(self) -> "Service":
        s, h = self.session, self.handler
        if h.shard:
            self._peers = Peers(s, h.name, on_change=self._sweep_now.set)
        for i, inp in enumerate(h.inputs):
            self._decls.append(s.declare_subscriber(inp.key, self._on_sample(i)))
        for q in h.queries:
            self._decls.append(s.declare_queryable(q.key, self._on_query(q)))
        for ck in h.cache_keys:
            self._decls.append(s.declare_queryable(ck, self._on_cache_query))
        base = f"{bus.SERVICES}/{h.name}/{self.instance}"
        self._decls.append(s.declare_queryable(base + "/status", self._on_status))
        self._decls.append(s.liveliness().declare_token(base))
        workers = [(f"w{k}" if k else "", self._work) for k in range(max(1, h.threads))]
        for name, target in workers + [("report", self._report_loop), ("cache", self._gets_loop)]:
            self._threads.append(threading.Thread(target=target, daemon=True,
                                                  name=f"{self.ident}{'/' + name if name else ''}"))
        if self.sweep_s is not None and any(inp.answers for inp in h.inputs):
            self._sweep_now.set()   # the first sweep at once: what was missed while down
            self._threads.append(threading.Thread(target=self._sweep_loop, daemon=True,
                                                  name=f"{self.ident}/sweep"))
        for t in self._threads:
            t.start()
        log.info("%s started", self.ident)
        return self

    def stop(self, timeout: float = 5.0) -> None:
        if self.handler.drain_on_stop:
            self.wait_idle(timeout)
        self._stop.set()
        self._sweep_now.set()
        with self._cv:
            self._cv.notify_all()
        for t in self._threads:
            t.join(timeout)
        for d in reversed(self._decls):
            try:
                d.undeclare()
            except zenoh.ZError:
                pass  # the session may already be closed
        self._decls.clear()
        if self._peers is not None:
            self._peers.close()
        self.handler.close()
        log.info("%s stopped", self.ident)

    def wait_idle(self, timeout: float | None = None) -> bool:
        """Block until every input received so far has been handled. Zenoh delivers puts
        asynchronously, so this is not a completion signal for messages still in flight:
        wait for the results themselves for that."""
        return self.idle.wait(timeout)

    # ------------------------------------------------------------------ intake (Zenoh's threads)
    def _on_sample(self, i: int):
        h = self.handler

        def cb(sample: zenoh.Sample) -> None:
            if sample.kind != zenoh.SampleKind.PUT:
                return
            key = str(sample.key_expr)
            if h.inline:
                self._inline(key, sample.payload.to_bytes())
            elif h.shard and not self._owns(key):
                self.inbox.bump("not_mine")
            else:
                self.offer(i, key, sample.payload.to_bytes())
        return cb

    def _inline(self, key: str, payload: bytes) -> None:
        with self._cv:
            self.inbox.frames_in += 1
        try:
            self.handler.on_message(key, payload)
        except Exception as exc:  # noqa: BLE001 - logged with the traceback; the callback goes on
            log.error("%s: %s: %s\n%s", self.ident, key, exc, traceback.format_exc())
            with self._cv:
                self.errors += 1

    def offer(self, i: int, key: str, payload: bytes, recovered: bool = False) -> bool:
        """Queue one input, never waiting (``Inbox.offer``); returns whether it was queued."""
        with self._cv:   # (reentrant) so the worker cannot go idle in between
            queued = self.inbox.offer(i, key, payload, recovered)
            if queued:
                self.idle.clear()
        return queued

    def _owns(self, key: str, msg=None) -> bool:
        if self._peers is None:
            return True
        peers = self._peers.instances() | {self.instance}
        if len(peers) == 1:
            return True
        return owner(self.handler.shard_key(key, msg), peers) == self.instance

    def _on_query(self, q: Input):
        def cb(query: zenoh.Query) -> None:
            with self._cv:
                self.inbox.frames_in += 1
                self.idle.clear()
                self.inbox.queries.append((q, query))
                self._cv.notify_all()
        return cb

    def _on_cache_query(self, query: zenoh.Query) -> None:
        key = str(query.key_expr)
        if is_exact(key):   # a dict lookup: answered here
            self._reply_cached(query)
            return
        with self._cv:      # a scan: on the cache thread, not Zenoh's
            self.inbox.gets.append(query)
            self._cv.notify_all()

    def _reply_cached(self, query: zenoh.Query) -> None:
        key, params = str(query.key_expr), query.parameters
        try:
            for k, v in self._cache.lookup(key, params) + self.handler.cached(key, params):
                query.reply(k, v)
        except (zenoh.ZError, ValueError) as e:
            log.warning("%s: cannot answer %s: %s", self.ident, key, e)
        finally:
            query.drop()

    def _on_status(self, query: zenoh.Query) -> None:
        query.reply(f"{bus.SERVICES}/{self.ident}/status", schemas.encode(self.status()))

    # ------------------------------------------------------------------ asking the bus
    def fetch(self, key: str, timeout: float = 2.0) -> bytes | None:
        """The latest payload of ``key`` from whoever holds it on the bus, or None."""
        local = self._cache.get(key)
        if local is not None:
            return local
        for reply in self.session.get(key, timeout=timeout):
            if reply.ok is not None:
                return reply.ok.payload.to_bytes()
        return None

    def fetch_all(self, key_expr: str, timeout: float = 5.0) -> list[tuple[str, bytes]]:
        """Every message the bus holds on ``key_expr`` (store and caches), each once."""
        seen, out = set(), []
        for k, p in bus.get_all(self.session, key_expr, timeout):
            if (k, p) not in seen:
                seen.add((k, p))
                out.append((k, p))
        return out

    def status(self):
        ib = self.inbox
        with self._cv:
            depth = ib.waiting()
            more = dict(ib.more, queued_bytes=ib.intake.nbytes, sessions_waiting=ib.intake.sessions)
            totals = (ib.frames_in, self.results_out, self.errors, ib.dropped)
        if self._peers is not None:
            more["peers"] = len(self._peers.instances() | {self.instance})
        more.update({k: int(v) for k, v in self.handler.counters().items()})
        return schemas.ServiceStatus(
            service=self.handler.name, instance=self.instance, started_ns=self.started_ns,
            time_ns=time.time_ns(), frames_in=totals[0], results_out=totals[1], errors=totals[2],
            dropped=totals[3], queue_depth=depth, version="findme.v1",
            counters={k: max(0, int(v)) for k, v in more.items()})

    # ------------------------------------------------------------------ threads
    def _next(self, done: bool):
        """The next thing to do (``done``: the caller finished one): queries first, a tick
        when due, then messages round-robin between sessions."""
        tick_s = self.handler.tick_s
        ib = self.inbox
        with self._cv:
            self._busy -= done
            while not self._stop.is_set():
                kind, item = None, None
                now = time.monotonic()
                if ib.queries:
                    kind, item = "query", ib.queries.popleft()
                elif tick_s is not None and now >= self._next_tick:
                    self._next_tick = now + tick_s
                    kind, item = "tick", now
                else:
                    item = ib.take()
                    kind = "msg" if item is not None else None
                if kind is not None:
                    self._busy += 1
                    return kind, item
                if not self._busy:
                    self.idle.set()
                wait = 0.5 if tick_s is None else max(0.0, min(0.5, self._next_tick - now))
                self._cv.wait(wait)
        return None, None

    def _work(self) -> None:
        done = False
        while True:
            kind, item = self._next(done)
            if kind is None:
                return
            if kind == "query":
                self._answer(*item)
            elif kind == "tick":
                self._tick(item)
            else:
                self.process(item.input, item.key, item.payload)
            done = True

    def _tick(self, now: float) -> None:
        try:
            for out in self.handler.tick(now):
                self.publish(out)
        except Exception as exc:  # noqa: BLE001 - reported and logged, the service goes on
            self.report(f"{bus.SERVICES}/{self.ident}", exc)

    def _report_loop(self) -> None:
        while True:
            with self._cv:
                while not self.inbox.reports and not self._stop.is_set():
                    self._cv.wait(0.5)
                if not self.inbox.reports:
                    return
                key, exc = self.inbox.reports.popleft()
            self.report(key, exc)

    def _gets_loop(self) -> None:
        while True:
            with self._cv:
                while not self.inbox.gets and not self._stop.is_set():
                    self._cv.wait(0.5)
                if not self.inbox.gets:
                    return
                query = self.inbox.gets.popleft()
            self._reply_cached(query)

    def _sweep_loop(self) -> None:
        """The first sweep (at start) and one after a change of instances look at the
        whole window the bus holds; periodic ones at what came since the last (with a
        margin): every input is looked at, none twice in full."""
        grace, done_to = 0.0, 0   # at start nothing is in flight to this instance yet
        while True:
            whole = self._sweep_now.wait(self.sweep_s) or not done_to
            if self._stop.is_set():
                return
            self._sweep_now.clear()
            now = time.time_ns()
            since = 0 if whole else max(0, done_to - int(1e9 * (self.grace_s + 5.0)))
            try:
                self.sweep(grace, since)
                done_to = now - int(grace * 1e9)
            except (zenoh.ZError, FindmeError) as e:
                log.warning("%s: recovery sweep failed: %s", self.ident, e)
            grace = self.grace_s

    def sweep(self, grace_s: float = 0.0, since_ns: int = 0) -> int:
        """Fetch and queue every unanswered input the bus holds (received since
        ``since_ns``) that is this instance's and not seen here (see ``recovery``); returns
        how many."""
        todo = recovery.unanswered(self.session, self.handler, int(grace_s * 1e9), time.time_ns(),
                                   since_ns=since_ns)
        n = 0
        for i, key, _ in todo:
            if self._stop.is_set():
                break
            if self.handler.shard and not self._owns(key):
                continue
            if self.inbox.knows(key):
                continue
            data = self.fetch(key)
            if data is not None and self.offer(i, key, data, recovered=True):
                n += 1
        self.inbox.bump("sweeps")
        if n:
            log.info("%s: recovered %d unanswered inputs from the bus", self.ident, n)
        return n

    # ------------------------------------------------------------------ handling (worker)
    def process(self, i: int, key: str, payload: bytes) -> None:
        """Decode, handle and publish one input (runs on the worker thread)."""
        inp = self.handler.inputs[i]
        try:
            msg = payload if inp.type is None else schemas.decode(inp.type, payload)
            if self.handler.shard and not self._owns(key, msg):
                self.inbox.bump("handed_over")   # the instances changed since it came:
                self.inbox.forget(key)           # its owner sweeps it up
                return
            outputs = self.handler.on_message(key, msg)
            for out in outputs:
                self.publish(out)
            self.inbox.bump("handled")
            self.inbox.handled(key)
        except Exception as exc:  # noqa: BLE001 - reported on the bus and logged, not swallowed
            self.report(key, exc)

    def _answer(self, q: Input, query: zenoh.Query) -> None:
        key = str(query.key_expr)
        try:
            if query.payload is None:
                raise SchemaError(f"query on {key} carries no {q.type.DESCRIPTOR.full_name} payload")
            msg = schemas.decode(q.type, query.payload.to_bytes())
            reply = self.handler.on_query(key, msg)
            query.reply(key, schemas.encode(reply))
            with self._cv:
                self.results_out += 1
        except Exception as exc:  # noqa: BLE001 - the asker gets the error, the log the reason
            ekey, err = self.report(key, exc)
            query.reply_err(schemas.encode(err))
        finally:
            query.drop()

    def publish(self, out: Output) -> None:
        """Cache (first: whoever reacts to the put may fetch it back at once), then put."""
        payload = schemas.encode(out.msg)
        if len(payload) > self.max_message_bytes:
            bus.put(self.session, out.key, payload, self.max_message_bytes)  # raises
        if out.cache:
            self._cache.put(out.key, payload)
        bus.put(self.session, out.key, payload, self.max_message_bytes)
        with self._cv:
            self.results_out += 1

    def report(self, key: str, exc: BaseException):
        """Publish and log an error about ``key``; returns (error key, Error)."""
        ekey, err = error_message(key, exc, self.ident)
        with self._cv:
            self.errors += 1
            self.inbox.count("error_" + schemas.ErrorCode.Name(err.code).removeprefix("ERROR_CODE_").lower())
        if isinstance(exc, FindmeError):
            log.warning("%s: %s: %s", self.ident, key, err.message)
        else:
            log.error("%s: %s: %s\n%s", self.ident, key, err.message, traceback.format_exc())
        try:
            bus.put(self.session, ekey, schemas.encode(err))
        except (FindmeError, zenoh.ZError) as e:
            log.error("%s: cannot publish the error on %s: %s", self.ident, ekey, e)
        return ekey, err


@dataclass
class Group:
    """Several services on one session (the embedded deployment)."""

    session: zenoh.Session
    services: list[Service] = field(default_factory=list)

    def add(self, handler: Handler, **kw) -> Service:
        svc = Service(handler, self.session, **kw).start()
        self.services.append(svc)
        return svc

    def stop(self) -> None:
        for s in reversed(self.services):
            s.stop()
