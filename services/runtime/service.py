"""Runs a pure handler on the bus: decode, handle, encode, publish; errors, counters,
liveliness, status, a latched cache of outputs, sharding, recovery, shutdown.

A *handler* (``handler.Handler``) knows nothing about Zenoh, so tests drive it directly;
``Service`` wires it to a session (delivery: issue 10, README "Delivery"):

* Zenoh's callbacks never wait: a message is queued in its session's bounded FIFO, served
  round-robin, or answered at once (OVERLOADED, TOO_LARGE) by a reporter thread
  (``inbox``). A blocked callback would stall the router's queue to this process until the
  router closes the link ("Unable to push non droppable network message ... Closing
  transport!") and everything on it is lost.
* worker threads (one; ``Handler.threads`` for stateless handlers) handle queries first,
  then messages, and ``tick`` when the handler asks; any exception becomes an Error on
  ``findme/<session>/error`` and a log line, and the service goes on.
* outputs marked ``cache`` are kept (bounded) and served on ``cache_keys`` (``cache``).
* with ``shard`` set, instances split the work by rendezvous hashing over the live
  instances (``peers``: a liveliness subscriber with history).
* a sweeper thread recovers unanswered inputs the bus still holds (``recovery``): at start,
  when an instance of the service comes or goes, and every ``sweep_s``.
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
from findme_io.imageio import decode_stats

from . import authority, bus, recovery
from .cache import CacheServer, OutputCache
from .handler import Handler, Input, Output, error_message
from .inbox import Inbox
from .peers import Peers, owner
from .peers import owner as shard_owner  # noqa: F401 - the name tests and tools use

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
                 seen_s: float = 180.0, max_wait_s: float | None = 10.0,
                 cache_age_s: float = 900.0):
        self.handler, self.session = handler, session
        self.instance = instance or uuid.uuid4().hex[:8]
        self.ident = f"{handler.name}/{self.instance}"
        self.inbox = Inbox(handler, self.ident, fifo_depth or handler.queue_depth, session_bytes,
                           queue_bytes, seen_s,
                           (handler.max_wait_s or max_wait_s) if handler.report_overload else None)
        self._cv = self.inbox.cv
        self.results_out = self.errors = 0
        self.started_ns = time.time_ns()
        self.max_message_bytes = max_message_bytes
        self.sweep_s, self.grace_s = sweep_s, grace_s
        self._stop = threading.Event()
        self._cancel = zenoh.CancellationToken()   # ends this service's queries of the bus
        self._sweep_now = threading.Event()
        self._cache = OutputCache(cache_bytes, cache_age_s)
        self._cache_server = CacheServer(self._cache, handler, self.ident)
        self._peers: Peers | None = None
        self._stale = False
        self._decls: list = []
        self._threads: list[threading.Thread] = []
        if handler.threads > 1 and handler.tick_s is not None:
            raise ValueError(f"{handler.name}: a handler with ticks has one worker thread")
        self.idle = threading.Event()   # set when nothing is queued or being handled
        self.idle.set()
        handler.fetch = self.fetch
        handler.fetch_all = self.fetch_all
        handler.backlog = self.inbox.session_waiting

    @property
    def counters(self) -> Counters:
        with self._cv:
            return Counters(self.inbox.frames_in, self.results_out, self.errors, self.inbox.dropped)

    # ------------------------------------------------------------------ lifecycle
    def start(self) -> "Service":
        s, h = self.session, self.handler
        if h.shard:
            self._peers = Peers(s, h.name, on_change=self._peers_changed)
        for i, inp in enumerate(h.inputs):
            self._decls.append(s.declare_subscriber(inp.key, self._on_sample(i)))
        for q in h.queries:
            self._decls.append(s.declare_queryable(q.key, self._on_query(q)))
        for ck in h.cache_keys:
            self._decls.append(s.declare_queryable(ck, self._cache_server.on_query))
        base = f"{bus.SERVICES}/{h.name}/{self.instance}"
        self._decls.append(s.declare_queryable(base + "/status", self._on_status))
        self._decls.append(s.liveliness().declare_token(base))
        workers = [(f"w{k}" if k else "", self._work) for k in range(max(1, h.threads))]
        for name, target in workers + [("report", self._report_loop)]:
            self._threads.append(threading.Thread(target=target, daemon=True,
                                                  name=f"{self.ident}{'/' + name if name else ''}"))
        self._threads.append(threading.Thread(target=self._cache_server.run, args=(self._stop,),
                                              daemon=True, name=f"{self.ident}/cache"))
        if self.sweep_s is not None and any(inp.answers for inp in h.inputs):
            self._sweep_now.set()   # the first sweep at once: what was missed while down
            self._threads.append(threading.Thread(target=recovery.Sweeper(self).run,
                                                  daemon=True, name=f"{self.ident}/sweep"))
        for t in self._threads:
            t.start()
        log.info("%s started", self.ident)
        return self

    def stop(self, timeout: float = 3.0) -> None:
        """Stop within about ``timeout`` s (after draining, for ``drain_on_stop``): a
        supervisor (``findme up``) kills what takes longer than 5 s."""
        if self.handler.drain_on_stop:
            self.wait_idle(timeout)
        self._stop.set()
        self._sweep_now.set()
        with self._cv:
            self._cv.notify_all()
        self._cache_server.wake()
        deadline = time.monotonic() + timeout   # all threads within ``timeout``; then what
        for t in self._threads:                  # still waits on the bus (a sweep's query)
            t.join(max(0.05, deadline - time.monotonic()))
        self._cancel.cancel()                    # is let go, and joined: no thread of ours
        for t in self._threads:                  # may be inside Zenoh when the process exits
            t.join(1.0)                          # (an abort: "exception not rethrown")
            if t.is_alive():
                log.error("%s: thread %s did not stop", self.ident, t.name)
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
            self.inbox.count("in_bytes", len(payload))
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

    def _peers_changed(self) -> None:
        """(Zenoh's thread) An instance came or went: sweep, and let the handler know on
        the worker thread (its state of sessions it owned before may be stale)."""
        self._sweep_now.set()
        self._stale = True

    def _owns(self, key: str, msg=None) -> bool:
        if self._peers is None:
            return True
        peers = self._peers.instances() | {self.instance}
        if len(peers) == 1:
            return True
        return owner(self.handler.shard_key(key, msg), peers) == self.instance

    def _on_query(self, q: Input):
        def cb(query: zenoh.Query) -> None:
            key = str(query.key_expr)
            size = 0 if query.payload is None else len(query.payload)
            with self._cv:
                self.idle.clear()
                refused = self.inbox.offer_query(q, key, size, query)
            if refused is not None:   # answered at once, from this callback: never queued
                query.reply_err(schemas.encode(error_message(key, refused, self.ident)[1]))
                query.drop()
        return cb

    def _on_status(self, query: zenoh.Query) -> None:
        query.reply(f"{bus.SERVICES}/{self.ident}/status", schemas.encode(self.status()))

    # ------------------------------------------------------------------ asking the bus
    def fetch(self, key: str, timeout: float = 2.0) -> bytes | None:
        """The latest payload of ``key``: this service's own output, or whoever holds it."""
        local = self._cache.get(key)
        if local is not None:
            return local
        t0 = time.perf_counter()
        try:
            return bus.fetch(self.session, key, timeout, self._cancel)
        finally:
            self._fetched(t0)

    def fetch_all(self, key_expr: str, timeout: float = 5.0) -> list[tuple[str, bytes]]:
        """Every message the bus holds on ``key_expr`` (store and caches), each once."""
        t0 = time.perf_counter()
        try:
            return list(dict.fromkeys(bus.get_all(self.session, key_expr, timeout,
                                                  cancel=self._cancel)))
        finally:
            self._fetched(t0)

    def _fetched(self, t0: float) -> None:
        """Count a query of the bus and the time it took (status: ``fetches``, ``fetch_us``)."""
        with self._cv:
            self.inbox.count("fetches")
            self.inbox.count("fetch_us", int(1e6 * (time.perf_counter() - t0)))

    def status(self):
        ib = self.inbox
        with self._cv:
            depth = ib.waiting()
            more = dict(ib.more, queued_bytes=ib.intake.nbytes, sessions_waiting=ib.intake.sessions)
            totals = (ib.frames_in, self.results_out, self.errors, ib.dropped)
        if self._peers is not None:
            more["peers"] = len(self._peers.instances() | {self.instance})
        more.update({k: int(v) for k, v in self.handler.counters().items()})
        more["cache_scans_refused"] = self._cache_server.refused
        more.update(decode_stats())
        return schemas.ServiceStatus(
            service=self.handler.name, instance=self.instance, started_ns=self.started_ns,
            time_ns=time.time_ns(), frames_in=totals[0], results_out=totals[1], errors=totals[2],
            dropped=totals[3], queue_depth=depth, version="findme.v1",
            counters={k: max(0, int(v)) for k, v in more.items()})

    # ------------------------------------------------------------------ threads
    def _work(self) -> None:
        done = False
        while True:
            kind, item = self.inbox.next_work(done, self._stop, self.handler.tick_s, self.idle)
            if kind is None:
                return
            if self._stale:
                self._stale = False
                self.handler.peers_changed()
            if kind == "query":
                self._answer(*item)
            elif kind == "tick":
                self._tick(item)
            else:
                self.process(item.input, item.key, item.payload, item.t)
            done = True

    def _tick(self, now: float) -> None:
        c0, t0 = time.thread_time(), time.perf_counter()
        try:
            for out in self.handler.tick(now):
                self.publish(out)
        except Exception as exc:  # noqa: BLE001 - reported and logged, the service goes on
            self.report(f"{bus.SERVICES}/{self.ident}", exc)
        finally:
            with self._cv:
                self.inbox.count("tick_us", int(1e6 * (time.perf_counter() - t0)))
                self.inbox.count("tick_cpu_us", int(1e6 * (time.thread_time() - c0)))

    def _report_loop(self) -> None:
        while True:
            with self._cv:
                while not self.inbox.reports and not self._stop.is_set():
                    self._cv.wait(0.5)
                if not self.inbox.reports:
                    return
                key, exc = self.inbox.reports.popleft()
            self.report(key, exc)

    def sweep(self, grace_s: float = 0.0, since_ns: int = 0) -> int:
        """Fetch and queue what this instance should have handled and nobody answered
        (``recovery.Sweeper.sweep``); returns how many."""
        return recovery.Sweeper(self).sweep(grace_s, since_ns)

    # ------------------------------------------------------------------ handling (worker)
    def process(self, i: int, key: str, payload: bytes, queued: float | None = None) -> None:
        """Decode, handle and publish one input (runs on the worker thread); ``queued``:
        when it was queued (monotonic s), for the queue-wait counters."""
        inp = self.handler.inputs[i]
        c0, t0 = time.thread_time(), time.perf_counter()
        if queued is not None:
            self.inbox.waited(time.monotonic() - queued)
        try:
            msg = payload if inp.type is None else schemas.decode(inp.type, payload)
            self.inbox.bump("pb_decode_us", int(1e6 * (time.perf_counter() - t0)))
            authority.check(key, msg)
            if self.handler.shard and not self._owns(key, msg):
                self.inbox.bump("handed_over")   # the instances changed since it came:
                self.inbox.forget(key)           # its owner sweeps it up
                return
            t0 = time.perf_counter()
            outputs = self.handler.on_message(key, msg)
            for out in outputs:
                self.publish(out)
            self.inbox.bump("handled")
            self.inbox.handled(key)
            log.info("%s: %s -> %s (%.0f ms)", self.ident, key,   # one line per message
                     ", ".join(o.key for o in outputs) or "nothing", 1e3 * (time.perf_counter() - t0))
        except Exception as exc:  # noqa: BLE001 - reported on the bus and logged, not swallowed
            self.report(key, exc)
        finally:
            self.inbox.spent(time.perf_counter() - t0, time.thread_time() - c0)

    def _answer(self, q: Input, query: zenoh.Query) -> None:
        key = str(query.key_expr)
        try:
            if query.payload is None:
                raise SchemaError(f"query on {key} carries no {q.type.DESCRIPTOR.full_name} payload")
            msg = schemas.decode(q.type, query.payload.to_bytes())
            authority.check(key, msg)
            reply = self.handler.on_query(key, msg)
            query.reply(key, schemas.encode(reply))
            with self._cv:
                self.results_out += 1
            log.info("%s: query %s answered", self.ident, key)
        except Exception as exc:  # noqa: BLE001 - the asker gets the error, the log the reason
            ekey, err = self.report(key, exc)
            query.reply_err(schemas.encode(err))
        finally:
            query.drop()

    def publish(self, out: Output) -> None:
        """Cache (first: whoever reacts to the put may fetch it back at once), then put."""
        t0 = time.perf_counter()
        payload = schemas.encode(out.msg)
        with self._cv:
            self.inbox.count("pb_encode_us", int(1e6 * (time.perf_counter() - t0)))
            self.inbox.count("out_bytes", len(payload))
        if len(payload) > self.max_message_bytes:
            bus.put(self.session, out.key, payload, self.max_message_bytes)  # raises
        if out.cache:
            self._cache.put(out.key, payload)
        with self._cv:   # counted first: a subscriber in this process hears it during the put
            self.results_out += 1
        bus.put(self.session, out.key, payload, self.max_message_bytes)

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
