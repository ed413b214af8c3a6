"""Per-session state of a handler, bounded: a session idle for ``idle_s`` seconds is evicted,
and beyond ``max_sessions`` the least recently used one is. An evicted session is not lost:
its messages are on the bus (the store's window, the services' caches, the recording), and
a handler rebuilds what it needs from there when the session comes back.
"""

from __future__ import annotations

import time
from collections import OrderedDict
from collections.abc import Callable


class SessionTable:
    """session id -> state, most recently used last.

    factory(session) makes the state of a session seen for the first time (a handler may
    rebuild it from the bus there); clock: monotonic seconds (injected for tests).
    """

    def __init__(self, factory: Callable[[str], object], idle_s: float = 600.0,
                 max_sessions: int = 1000, clock: Callable[[], float] = time.monotonic):
        if idle_s <= 0 or max_sessions < 1:
            raise ValueError(f"idle_s must be > 0 and max_sessions >= 1, got {idle_s}, {max_sessions}")
        self.factory, self.idle_s, self.max_sessions = factory, idle_s, max_sessions
        self.clock = clock
        self._items: OrderedDict[str, tuple[float, object]] = OrderedDict()
        self.evicted = 0

    def __len__(self) -> int:
        return len(self._items)

    def __contains__(self, session: str) -> bool:
        return session in self._items

    def get(self, session: str):
        """The state of ``session`` (made by the factory if new), marked as used now."""
        now = self.clock()
        hit = self._items.pop(session, None)
        state = hit[1] if hit is not None else None
        self.expire(now)
        if state is None:
            state = self.factory(session)
        self._items[session] = (now, state)
        while len(self._items) > self.max_sessions:
            self._items.popitem(last=False)
            self.evicted += 1
        return state

    def peek(self, session: str):
        """The state of ``session`` if held, without marking it used; else None."""
        hit = self._items.get(session)
        return hit[1] if hit is not None else None

    def expire(self, now: float | None = None) -> list[str]:
        """Evict every session idle for more than ``idle_s``; returns their ids."""
        now = self.clock() if now is None else now
        gone = []
        while self._items:
            session, (t, _) = next(iter(self._items.items()))
            if now - t <= self.idle_s:
                break
            del self._items[session]
            gone.append(session)
        self.evicted += len(gone)
        return gone

    def items(self):
        return [(s, st) for s, (_, st) in self._items.items()]
