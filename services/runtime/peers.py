"""Who is alive on the bus: the live instances of services, from their liveliness tokens
``findme/@services/<name>/<instance>``, and which instance owns a piece of sharded work.

Measured (zenoh 1.10.2, client of a router; ``bench/bench_liveliness.py``): liveliness
*queries* come back empty at once, now and then, right after liveliness subscribers were
declared and undeclared on the same session (``bus.wait_alive``, as a client waiting for
the services does): in 5 runs of 60 back-to-back queries, 8, 0, 1, 16 and 0 saw none or
not all; the same queries later, 0.25 s apart or on fresh sessions saw all every time. So
a set of instances built from repeated queries flickers. A liveliness *subscriber with
history*, declared once and kept for the session's life, is told of every token that
exists when it is declared and of every later PUT/DELETE: that is what ``Peers`` keeps,
seeded by one query when it starts. ``findme status`` asks every instance for its status
(one query to all) and adds the tokens of a subscriber like it.
"""

from __future__ import annotations

import hashlib
import threading

import zenoh

from . import bus


def owner(shard_key: str, instances) -> str:
    """The instance that handles ``shard_key`` among ``instances``: rendezvous hashing (the
    highest hash of instance and key), so an instance joining or leaving moves only the work
    that goes to or came from it. (blake2b, not crc32: crc32 is linear in its input, and
    ``crc32(key) % n`` sent frames 0-3 of every session to the same one of two instances.)"""
    return max(sorted(instances), key=lambda i: hashlib.blake2b(
        f"{i}\0{shard_key}".encode(), digest_size=8).digest())


class Peers:
    """The live instances under ``findme/@services/<name>/*`` (``name`` "*" = every service),
    kept by a liveliness subscriber with history. ``on_change()`` is called (from Zenoh's
    thread: keep it short) whenever the set changes."""

    def __init__(self, session: zenoh.Session, name: str = "*", on_change=None,
                 seed_timeout: float = 2.0):
        self.name, self.on_change = name, on_change
        self._lock = threading.Condition()
        self._live: set[tuple[str, str]] = set()   # (service, instance)
        self.changes = 0
        pattern = f"{bus.SERVICES}/{name}/*"
        self._sub = session.liveliness().declare_subscriber(pattern, self._on_sample, history=True)
        try:  # the history arrives asynchronously: one query makes the start state known now
            for r in session.liveliness().get(pattern, timeout=seed_timeout):
                if r.ok is not None:
                    self._update(str(r.ok.key_expr), True)
        except zenoh.ZError:
            pass  # the subscriber still fills the set

    @staticmethod
    def _parse(k: str) -> tuple[str, str]:
        name, inst = k.split("/")[-2:]
        return name, inst

    def _update(self, k: str, alive: bool) -> None:
        ident = self._parse(k)
        with self._lock:
            before = ident in self._live
            if alive:
                self._live.add(ident)
            else:
                self._live.discard(ident)
            changed = before != alive
            self.changes += changed
            self._lock.notify_all()
        if changed and self.on_change is not None:
            self.on_change()

    def _on_sample(self, sample: zenoh.Sample) -> None:
        self._update(str(sample.key_expr), sample.kind == zenoh.SampleKind.PUT)

    def instances(self, name: str | None = None) -> set[str]:
        """Live instance ids of service ``name`` (default: the one this watches)."""
        name = self.name if name is None else name
        with self._lock:
            return {i for n, i in self._live if name == "*" or n == name}

    def wait_for(self, predicate, timeout: float) -> bool:
        """Block until ``predicate(instances())`` holds (False after ``timeout`` s)."""
        with self._lock:
            return self._lock.wait_for(lambda: predicate(
                {i for n, i in self._live if self.name == "*" or n == self.name}), timeout)

    def all(self) -> set[tuple[str, str]]:
        """Every live (service, instance)."""
        with self._lock:
            return set(self._live)

    def close(self) -> None:
        try:
            self._sub.undeclare()
        except zenoh.ZError:
            pass  # the session may already be closed
