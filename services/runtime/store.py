"""The store service: what was published on the bus recently, for whoever missed it.

    findme/<session>/**  ->  held; answered to ``get`` on any of its keys

A service that was down (killed and restarted, or a new instance) asks the store for the
inputs published while it was away and for the answers already given, and handles what is
unanswered (``runtime.recovery``). Frames may come from any Zenoh client doing plain puts
(a phone app of someone else's making), so recovery cannot rely on the sender's own cache:
the store, a component that is up, holds them. Zenoh's advanced publisher cache does the
same for its own publishers only, one publisher per key, and our keys change per photo.

What it holds (both bounded; the oldest go first):

* every message received in the last ``window_s`` seconds (60 s), at most ``max_bytes``;
  one per key (the latest), except ``error`` keys, where every Error is kept;
* beyond the window, the latest message of each key of at most ``latch_bytes`` (64 kB)
  that is not a frame or an error (hypotheses, selections, scenes, motions, poses,
  trajectories) for ``latch_s`` seconds (15 min), at most ``max_latched_bytes``: enough to
  pick a quiet session up again.

Query parameters (``get("findme/*/frame/*?meta;since=<ns>")``): ``meta`` replies carry
``b"<receive time ns> <payload bytes>"`` instead of the payload (a listing); ``since``
keeps messages received at or after a time (ns since the epoch). Replies come in receive
order; ask with consolidation NONE (``bus.get_all``) or Zenoh keeps one reply per key.
Several stores may run: they answer alike, the asker dedupes.
"""

from __future__ import annotations

import itertools
import threading
import time
from collections import OrderedDict

import zenoh

from .handler import Handler, Input

_NO_LATCH = {"frame", "error"}


class StoreHandler(Handler):
    name = "store"
    background = True    # not on the way from a photo to its pose (``Handler.background``)
    inline = True              # on_message is a dict insert: done in Zenoh's callback
    report_overload = False
    cache_keys = ("findme/*/**",)

    def __init__(self, window_s: float = 60.0, max_bytes: int = 512 << 20,
                 latch_s: float = 900.0, latch_bytes: int = 64 << 10,
                 max_latched_bytes: int = 64 << 20, clock=time.time_ns):
        self.inputs = (Input("findme/*/**", None),)
        self.window_ns, self.max_bytes = int(window_s * 1e9), max_bytes
        self.latch_ns, self.latch_bytes = int(latch_s * 1e9), latch_bytes
        self.max_latched_bytes = max_latched_bytes
        self.clock = clock
        self._lock = threading.Lock()
        self._recent: OrderedDict[object, tuple[str, int, bytes]] = OrderedDict()
        self._latched: OrderedDict[str, tuple[int, bytes]] = OrderedDict()
        self._bytes = self._latched_bytes = 0
        self._seq = itertools.count()
        self.held = self.expired = 0

    # ------------------------------------------------------------------ holding
    def on_message(self, key, payload):
        t = self.clock()
        parts = key.split("/")
        kind = parts[2] if len(parts) > 2 else ""
        with self._lock:
            ident = (key, next(self._seq)) if kind == "error" else key
            old = self._recent.pop(ident, None)
            if old is not None:
                self._bytes -= len(old[2])
            self._recent[ident] = (key, t, payload)
            self._bytes += len(payload)
            if kind not in _NO_LATCH and len(payload) <= self.latch_bytes:
                old = self._latched.pop(key, None)
                if old is not None:
                    self._latched_bytes -= len(old[1])
                self._latched[key] = (t, payload)
                self._latched_bytes += len(payload)
            self.held += 1
            self._expire(t)
        return []

    def _expire(self, now: int) -> None:
        while self._recent:
            ident, (_, t, p) = next(iter(self._recent.items()))
            if now - t <= self.window_ns and self._bytes <= self.max_bytes:
                break
            del self._recent[ident]
            self._bytes -= len(p)
            self.expired += 1
        while self._latched:
            k, (t, p) = next(iter(self._latched.items()))
            if now - t <= self.latch_ns and self._latched_bytes <= self.max_latched_bytes:
                break
            del self._latched[k]
            self._latched_bytes -= len(p)

    # ------------------------------------------------------------------ answering
    def cached(self, key_expr: str, parameters) -> list[tuple[str, bytes]]:
        """Held messages on keys intersecting ``key_expr`` (see the module docstring)."""
        meta = parameters.get("meta") is not None if parameters is not None else False
        since = int(parameters.get("since") or 0) if parameters is not None else 0
        want = zenoh.KeyExpr(key_expr)
        exact = not any(c in key_expr for c in "*$")
        with self._lock:
            self._expire(self.clock())
            if exact:
                hits = [v for v in [self._recent.get(key_expr)] if v is not None]
                if not hits and key_expr.split("/")[2:3] == ["error"]:
                    hits = [v for v in self._recent.values() if v[0] == key_expr]
                if not hits and key_expr in self._latched:
                    hits = [(key_expr, *self._latched[key_expr])]
            else:
                hits = [v for v in self._recent.values() if want.intersects(zenoh.KeyExpr(v[0]))]
                seen = {v[0] for v in hits}
                old = [(k, t, p) for k, (t, p) in self._latched.items()
                       if k not in seen and want.intersects(zenoh.KeyExpr(k))]
                hits = old + hits
        hits = [h for h in hits if h[1] >= since]
        if meta:
            return [(k, f"{t} {len(p)}".encode()) for k, t, p in hits]
        return [(k, p) for k, _, p in hits]

    def counters(self):
        with self._lock:
            return {"held": self.held, "expired": self.expired, "recent": len(self._recent),
                    "recent_bytes": self._bytes, "latched": len(self._latched),
                    "latched_bytes": self._latched_bytes}


def make_store(args) -> StoreHandler:
    """``findme serve store [--window S] [--latch S]``."""
    return StoreHandler(window_s=getattr(args, "window", None) or 60.0,
                        latch_s=getattr(args, "latch", None) or 900.0)
