"""Runs a pure handler on the bus: decode, handle, encode, publish; errors, counters,
liveliness, status, a latched cache of outputs, sharding among instances, shutdown.

A *handler* (``handler.Handler``) knows nothing about Zenoh: it declares its inputs and
queries and turns one decoded message into outputs, so tests drive it directly. ``Service``
wires it to a session:

* inputs with policy ``"all"`` go through a bounded FIFO; a full FIFO blocks the sender
  (backpressure), nothing is dropped. Inputs with policy ``"latest"`` keep the newest
  ``depth`` messages; each one pushed out is counted as dropped.
* one worker thread handles queries first, then messages in arrival order.
* any FindmeError becomes an ``Error`` on ``findme/<session>/error`` and a log line; any
  other exception too (code INTERNAL, with the traceback in the log). The service goes on.
* outputs marked ``cache`` are kept (bounded) and served to ``get`` queries on the
  handler's ``cache_keys``, so a service that starts late or restarts can fetch what it
  missed: nothing lives only in one service's memory.
* with ``shard`` set, instances of the same service split the work: each handles the
  messages whose shard key hashes to its rank among the live instances.
"""

from __future__ import annotations

import hashlib
import logging
import threading
import time
import traceback
import uuid
from collections import OrderedDict, deque
from dataclasses import dataclass, field

import zenoh

import schemas
from findme_core.errors import FindmeError, SchemaError

from . import authority, bus
from .handler import Handler, Input, Output, error_message

log = logging.getLogger("findme.services")


def shard_owner(shard_key: str, instances) -> str:
    """The instance (of the live ``instances`` of one service) that handles a message with
    this shard key: rendezvous hashing (the instance with the highest hash of instance and
    key), so an instance leaving moves only its own keys. (``crc32(key) % n`` sent frames
    0-3 of every session to the same one of two instances: crc32 is linear in its input.)"""
    return max(sorted(instances), key=lambda i: hashlib.blake2b(
        f"{i}\0{shard_key}".encode(), digest_size=8).digest())


@dataclass
class Counters:
    frames_in: int = 0
    results_out: int = 0
    errors: int = 0
    dropped: int = 0


class Service:
    """A handler running on a Zenoh session (see the module docstring)."""

    def __init__(self, handler: Handler, session: zenoh.Session, instance: str | None = None,
                 fifo_depth: int = 256, cache_bytes: int = 64 * 1024 * 1024,
                 max_message_bytes: int = bus.MAX_MESSAGE_BYTES):
        self.handler, self.session = handler, session
        self.instance = instance or uuid.uuid4().hex[:8]
        self.ident = f"{handler.name}/{self.instance}"
        self.counters = Counters()
        self.started_ns = time.time_ns()
        self.max_message_bytes = max_message_bytes
        self._cv = threading.Condition()
        self._fifo: deque = deque()
        self._fifo_depth = fifo_depth
        self._latest = [deque() for _ in handler.inputs]
        self._queries: deque = deque()
        self._stop = threading.Event()
        self._cache: OrderedDict[str, bytes] = OrderedDict()
        self._cache_bytes, self._cache_limit = 0, cache_bytes
        self._peers: set[str] = set()
        self._decls: list = []
        self._thread: threading.Thread | None = None
        self.idle = threading.Event()   # set when nothing is queued or being handled
        self.idle.set()
        handler.fetch = self.fetch

    # ------------------------------------------------------------------ lifecycle
    def start(self) -> "Service":
        s, h = self.session, self.handler
        for i, inp in enumerate(h.inputs):
            self._decls.append(s.declare_subscriber(inp.key, self._on_sample(i)))
        for q in h.queries:
            self._decls.append(s.declare_queryable(q.key, self._on_query(q)))
        for ck in h.cache_keys:
            self._decls.append(s.declare_queryable(ck, self._on_cache_query))
        base = f"{bus.SERVICES}/{h.name}/{self.instance}"
        self._decls.append(s.declare_queryable(base + "/status", self._on_status))
        if h.shard:
            self._peers = {self.instance}
            self._decls.append(s.liveliness().declare_subscriber(
                f"{bus.SERVICES}/{h.name}/*", self._on_peer, history=True))
        self._decls.append(s.liveliness().declare_token(base))
        self._thread = threading.Thread(target=self._work, name=self.ident, daemon=True)
        self._thread.start()
        log.info("%s started", self.ident)
        return self

    def stop(self, timeout: float = 5.0) -> None:
        if self.handler.drain_on_stop:
            self.wait_idle(timeout)
        self._stop.set()
        with self._cv:
            self._cv.notify_all()
        if self._thread:
            self._thread.join(timeout)
        for d in reversed(self._decls):
            try:
                d.undeclare()
            except zenoh.ZError:
                pass  # the session may already be closed
        self._decls.clear()
        self.handler.close()
        log.info("%s stopped", self.ident)

    def wait_idle(self, timeout: float | None = None) -> bool:
        """Block until every input received so far has been handled. Zenoh delivers puts
        asynchronously, so this is not a completion signal for messages still in flight:
        wait for the results themselves for that."""
        return self.idle.wait(timeout)

    # ------------------------------------------------------------------ zenoh callbacks
    def _on_sample(self, i: int):
        inp = self.handler.inputs[i]

        def cb(sample: zenoh.Sample) -> None:
            if sample.kind != zenoh.SampleKind.PUT:
                return
            item = (i, str(sample.key_expr), sample.payload.to_bytes())
            with self._cv:
                self.counters.frames_in += 1
                self.idle.clear()
                if inp.policy == "latest":
                    q = self._latest[i]
                    if len(q) >= inp.depth:
                        q.popleft()
                        self.counters.dropped += 1
                    q.append(item)
                else:
                    while len(self._fifo) >= self._fifo_depth and not self._stop.is_set():
                        self._cv.wait(0.1)  # backpressure: the sender waits
                    self._fifo.append(item)
                self._cv.notify_all()
        return cb

    def _on_query(self, q: Input):
        def cb(query: zenoh.Query) -> None:
            with self._cv:
                self.counters.frames_in += 1
                self.idle.clear()
                self._queries.append((q, query))
                self._cv.notify_all()
        return cb

    def _on_cache_query(self, query: zenoh.Query) -> None:
        want = zenoh.KeyExpr(str(query.key_expr))
        with self._cv:
            hits = [(k, v) for k, v in self._cache.items() if want.intersects(zenoh.KeyExpr(k))]
        for k, v in hits:
            query.reply(k, v)

    def _on_status(self, query: zenoh.Query) -> None:
        query.reply(str(query.key_expr), schemas.encode(self.status()))

    def _on_peer(self, sample: zenoh.Sample) -> None:
        inst = str(sample.key_expr).rsplit("/", 1)[-1]
        with self._cv:
            if sample.kind == zenoh.SampleKind.PUT:
                self._peers.add(inst)
            elif inst != self.instance:
                self._peers.discard(inst)

    def fetch(self, key: str, timeout: float = 2.0) -> bytes | None:
        """The latest payload of ``key`` from whoever caches it on the bus, or None."""
        for reply in self.session.get(key, timeout=timeout):
            if reply.ok is not None:
                return reply.ok.payload.to_bytes()
        return None

    def status(self):
        c = self.counters
        with self._cv:
            depth = len(self._fifo) + sum(map(len, self._latest)) + len(self._queries)
        return schemas.ServiceStatus(
            service=self.handler.name, instance=self.instance, started_ns=self.started_ns,
            time_ns=time.time_ns(), frames_in=c.frames_in, results_out=c.results_out,
            errors=c.errors, dropped=c.dropped, queue_depth=depth, version="findme.v1",
            counters={k: int(v) for k, v in self.handler.counters().items()})

    # ------------------------------------------------------------------ the worker
    def _next(self):
        with self._cv:
            while not self._stop.is_set():
                if self._queries:
                    return "query", self._queries.popleft()
                if self._fifo:
                    item = self._fifo.popleft()
                    self._cv.notify_all()
                    return "msg", item
                for q in self._latest:
                    if q:
                        return "msg", q.popleft()
                self.idle.set()
                self._cv.wait(0.5)
        return None, None

    def _work(self) -> None:
        while True:
            kind, item = self._next()
            if kind is None:
                return
            if kind == "query":
                self._answer(*item)
            else:
                self.process(*item)
            with self._cv:
                if not (self._queries or self._fifo or any(self._latest)):
                    self.idle.set()

    def _mine(self, key: str, msg) -> bool:
        if not self.handler.shard:
            return True
        with self._cv:
            peers = self._peers | {self.instance}
        return shard_owner(self.handler.shard_key(key, msg), peers) == self.instance

    def process(self, i: int, key: str, payload: bytes) -> None:
        """Decode, handle and publish one input (runs on the worker thread)."""
        inp = self.handler.inputs[i]
        try:
            msg = payload if inp.type is None else schemas.decode(inp.type, payload)
            authority.check(key, msg)
            if not self._mine(key, msg):
                return
            t0 = time.perf_counter()
            outputs = self.handler.on_message(key, msg)
            for out in outputs:
                self.publish(out)
            log.info("%s: %s -> %s (%.0f ms)", self.ident, key,   # one line per message
                     ", ".join(o.key for o in outputs) or "nothing", 1e3 * (time.perf_counter() - t0))
        except Exception as exc:  # noqa: BLE001 - reported on the bus and logged, not swallowed
            self.report(key, exc)

    def _answer(self, q: Input, query: zenoh.Query) -> None:
        key = str(query.key_expr)
        try:
            if query.payload is None:
                raise SchemaError(f"query on {key} carries no {q.type.DESCRIPTOR.full_name} payload")
            msg = schemas.decode(q.type, query.payload.to_bytes())
            authority.check(key, msg)
            reply = self.handler.on_query(key, msg)
            query.reply(key, schemas.encode(reply))
            self.counters.results_out += 1
            log.info("%s: query %s answered", self.ident, key)
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
            with self._cv:
                old = self._cache.pop(out.key, None)
                self._cache_bytes += len(payload) - (len(old) if old else 0)
                self._cache[out.key] = payload
                while self._cache_bytes > self._cache_limit and len(self._cache) > 1:
                    _, v = self._cache.popitem(last=False)
                    self._cache_bytes -= len(v)
        bus.put(self.session, out.key, payload, self.max_message_bytes)
        self.counters.results_out += 1

    def report(self, key: str, exc: BaseException):
        """Publish and log an error about ``key``; returns (error key, Error)."""
        self.counters.errors += 1
        ekey, err = error_message(key, exc, self.ident)
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
