"""A service's latched outputs: the latest payload of each key it published, bounded in
bytes and age (oldest first out: what a session still needs is recent), served to ``get`` queries on the handler's ``cache_keys`` so a
service that starts late or restarts fetches what it missed.

Answers the store's query protocol too (``runtime.store``): with the parameter ``meta`` a
reply carries ``b"<publish time ns> <bytes>"`` instead of the payload (a listing, used by
recovery to see which inputs are answered); ``since=<ns>`` keeps newer ones.
"""

from __future__ import annotations

import logging
import threading
import time
from collections import OrderedDict, deque

import zenoh

log = logging.getLogger("findme.services")


def is_exact(key_expr: str) -> bool:
    """A key expression without wildcards (a dict lookup, not a scan)."""
    return not any(c in key_expr for c in "*$")


class OutputCache:
    def __init__(self, max_bytes: int = 64 * 1024 * 1024, max_age_s: float = 900.0,
                 clock=time.time_ns):
        self.max_bytes, self.clock = max_bytes, clock
        self.max_age_ns = int(max_age_s * 1e9)
        self._items: OrderedDict[str, tuple[int, bytes]] = OrderedDict()
        self._bytes = 0
        self._lock = threading.Lock()

    def __len__(self) -> int:
        return len(self._items)

    def put(self, key: str, payload: bytes) -> None:
        with self._lock:
            old = self._items.pop(key, None)
            self._bytes += len(payload) - (len(old[1]) if old else 0)
            now = self.clock()
            self._items[key] = (now, payload)
            while len(self._items) > 1:
                t, v = next(iter(self._items.values()))
                if self._bytes <= self.max_bytes and now - t <= self.max_age_ns:
                    break
                self._items.popitem(last=False)
                self._bytes -= len(v)

    def get(self, key: str) -> bytes | None:
        with self._lock:
            hit = self._items.get(key)
            return hit[1] if hit else None

    def lookup(self, key_expr: str, parameters=None) -> list[tuple[str, bytes]]:
        """(key, payload or listing) of every held key intersecting ``key_expr``."""
        meta = parameters is not None and parameters.get("meta") is not None
        since = int(parameters.get("since") or 0) if parameters is not None else 0
        with self._lock:
            if is_exact(key_expr):
                hit = self._items.get(key_expr)
                hits = [(key_expr, *hit)] if hit else []
            else:
                want = zenoh.KeyExpr(key_expr)
                hits = [(k, t, p) for k, (t, p) in self._items.items()
                        if want.intersects(zenoh.KeyExpr(k))]
        hits = [h for h in hits if h[1] >= since]
        if meta:
            return [(k, f"{t} {len(p)}".encode()) for k, t, p in hits]
        return [(k, p) for k, _, p in hits]


class CacheServer:
    """Answers ``get`` on a handler's ``cache_keys`` from its ``OutputCache`` and the
    handler's own ``cached`` (the store): an exact key in Zenoh's callback (a dict lookup),
    a key expression with wildcards (a scan) on this server's thread, never Zenoh's. At most
    ``max_scans`` scans wait; beyond, a scan is closed with no reply from this service (the
    asker gets the others'), counted in ``refused``."""

    def __init__(self, cache: OutputCache, handler, ident: str, max_scans: int = 256):
        self.cache, self.handler, self.ident = cache, handler, ident
        self.max_scans, self.refused = max_scans, 0
        self._cv = threading.Condition()
        self._scans: deque = deque()

    def on_query(self, query: zenoh.Query) -> None:
        if is_exact(str(query.key_expr)):
            self.reply(query)
            return
        with self._cv:
            if len(self._scans) >= self.max_scans:
                self.refused += 1
            else:
                self._scans.append(query)
                self._cv.notify_all()
                return
        log.warning("%s: %d scans of the cache wait: %s closed unanswered", self.ident,
                    self.max_scans, query.key_expr)
        query.drop()

    def reply(self, query: zenoh.Query) -> None:
        key, params = str(query.key_expr), query.parameters
        try:
            for k, v in self.cache.lookup(key, params) + self.handler.cached(key, params):
                query.reply(k, v)
        except (zenoh.ZError, ValueError) as e:
            log.warning("%s: cannot answer %s: %s", self.ident, key, e)
        finally:
            query.drop()

    def run(self, stop: threading.Event) -> None:
        """The scan thread: until ``stop`` is set (``wake`` to notice it at once)."""
        while True:
            with self._cv:
                while not self._scans and not stop.is_set():
                    self._cv.wait(0.5)
                if not self._scans:
                    return
                query = self._scans.popleft()
            self.reply(query)

    def wake(self) -> None:
        with self._cv:
            self._cv.notify_all()
