"""What a service has received and not handled yet: one bounded FIFO per session, served
round-robin, so one phone's burst (four 12 MB frames) waits behind itself and not in front
of another phone's photo.

Bounds (messages and bytes per session, bytes in all) are checked when a message is
offered; a message that does not fit is refused and the caller answers it (OVERLOADED), so
nothing waits without bound and nothing is lost without a word. An input with the "latest"
policy instead pushes out the oldest of its kind in that session (superseded, answered by
the caller too). Pure bookkeeping, no threads, no Zenoh: ``Service`` holds the lock.
"""

from __future__ import annotations

from collections import OrderedDict, deque
from dataclasses import dataclass


@dataclass
class Item:
    """One received message: ``input`` is the index of the handler's Input it came on."""

    input: int
    key: str
    payload: bytes
    session: str
    recovered: bool = False   # fetched from the bus by a recovery sweep, not received live
    t: float = 0.0            # when it was queued (monotonic s)

    @property
    def nbytes(self) -> int:
        return len(self.payload) + len(self.key)


class Intake:
    """Per-session bounded FIFOs served round-robin.

    session_depth: messages a session may have waiting; session_bytes / total_bytes: payload
    bytes a session / all sessions may have waiting. A message larger than session_bytes is
    still taken when its session has nothing else waiting (and total_bytes allows): one
    large photo is not an overload.
    """

    def __init__(self, session_depth: int = 16, session_bytes: int = 64 << 20,
                 total_bytes: int = 512 << 20):
        if session_depth < 1:
            raise ValueError(f"session_depth must be at least 1, got {session_depth}")
        self.session_depth, self.session_bytes = session_depth, session_bytes
        self.total_bytes = total_bytes
        self._q: OrderedDict[str, deque[Item]] = OrderedDict()
        self._bytes: dict[str, int] = {}
        self.nbytes = 0
        self._n = 0

    def __len__(self) -> int:
        return self._n

    @property
    def sessions(self) -> int:
        """Sessions with something waiting."""
        return len(self._q)

    def waiting(self, session: str) -> int:
        """Messages of ``session`` waiting."""
        q = self._q.get(session)
        return len(q) if q else 0

    def offer(self, item: Item, latest: int | None = None) -> tuple[bool, list[Item], str]:
        """Queue ``item``. Returns (accepted, superseded items, why it was refused).

        latest: keep at most this many items of ``item.input`` in the session, pushing out
        the oldest (they are returned: the caller answers them)."""
        q = self._q.get(item.session)
        superseded: list[Item] = []
        if latest is not None and q:
            same = [x for x in q if x.input == item.input]
            for old in same[:max(0, len(same) - latest + 1)]:
                q.remove(old)
                self._account(old, -1)
                superseded.append(old)
        n = len(q) if q else 0
        sb = self._bytes.get(item.session, 0)
        if n >= self.session_depth:
            return False, superseded, (f"session {item.session!r} already has {n} messages "
                                       "waiting (the most it may)")
        if n and sb + item.nbytes > self.session_bytes:
            return False, superseded, (f"session {item.session!r} already has "
                                       f"{sb / 1e6:.1f} MB waiting (at most "
                                       f"{self.session_bytes / 1e6:.0f} MB)")
        if self.nbytes + item.nbytes > self.total_bytes:
            return False, superseded, (f"{self.nbytes / 1e6:.1f} MB are waiting in all sessions "
                                       f"(at most {self.total_bytes / 1e6:.0f} MB)")
        if q is None:
            q = self._q[item.session] = deque()
        q.append(item)
        self._account(item, +1)
        return True, superseded, ""

    def _account(self, item: Item, sign: int) -> None:
        self._n += sign
        self.nbytes += sign * item.nbytes
        self._bytes[item.session] = self._bytes.get(item.session, 0) + sign * item.nbytes
        if not self._bytes[item.session]:
            del self._bytes[item.session]

    def pop(self) -> Item | None:
        """The oldest item of the next session in turn (round-robin), or None."""
        if not self._q:
            return None
        session, q = next(iter(self._q.items()))
        item = q.popleft()
        self._account(item, -1)
        if q:
            self._q.move_to_end(session)
        else:
            del self._q[session]
        return item

    def clear(self) -> list[Item]:
        """Everything waiting, removed (in no particular order)."""
        out = [x for q in self._q.values() for x in q]
        self._q.clear()
        self._bytes.clear()
        self.nbytes = self._n = 0
        return out
