"""The Zenoh bus: configuration, keys, and reliable, size-checked publishing.

Keys (DESIGN.md): ``findme/<session>/frame/<n>``, ``hypotheses/<n>``, ``selection/<n>``,
``scene/<n>``, ``motion/<a>/<b>``, ``pose/<n>``, ``trajectory``, ``plan``, ``measure``
(queryable), ``error``; services announce themselves with liveliness tokens
``findme/@services/<name>/<id>`` and answer ``.../status`` queries.

Traps this module handles (STACK-NOTES.md): multicast scouting is off and every session has
explicit endpoints; peers listen on 127.0.0.1 unless told otherwise; the connect retry is
set as a whole object; puts use CongestionControl.BLOCK (DROP silently loses large
messages) and the sender enforces a size limit because Zenoh drops oversized messages
without a word.
"""

from __future__ import annotations

import json
import re
import threading
from dataclasses import dataclass, field

import zenoh

from findme_core.errors import BusError

ROOT = "findme"
SERVICES = f"{ROOT}/@services"
#: Largest payload a service sends (a 12 MP JPEG is ~5 MB). Zenoh's own default limit on a
#: peer's link is larger; anything above this is refused with a clear error at the sender.
MAX_MESSAGE_BYTES = 16 * 1024 * 1024
#: kinds whose message is a session's latest state, republished as it grows (odometry after
#: each batch of poses, the mapper once per batch of ready photos: how photos batch is
#: timing), so only the last one is compared
LATEST_STATE_KINDS = ("trajectory", "plan")

_SESSION_RE = re.compile(r"[A-Za-z0-9_-][A-Za-z0-9_.-]{0,127}\Z")


# ---------------------------------------------------------------------------------- keys
def key(session: str, kind: str, *parts) -> str:
    """``findme/<session>/<kind>[/<part>...]`` for a valid session id."""
    if not _SESSION_RE.match(session or ""):
        raise BusError(f"session id {session!r} is not valid (letters, digits, _ . -; "
                       "at most 128 characters)")
    return "/".join([ROOT, session, kind, *map(str, parts)])


@dataclass(frozen=True)
class Key:
    """A parsed session key."""

    session: str
    kind: str
    parts: tuple[str, ...]

    def index(self, i: int = 0) -> int:
        try:
            return int(self.parts[i])
        except (IndexError, ValueError):
            raise BusError(f"key part {i} of {self} is not a photo number") from None

    def __str__(self) -> str:
        return "/".join([ROOT, self.session, self.kind, *self.parts])


def parse_key(k: str) -> Key:
    """Split ``findme/<session>/<kind>/...``; BusError for anything else."""
    parts = str(k).split("/")
    if len(parts) < 3 or parts[0] != ROOT or parts[1].startswith("@"):
        raise BusError(f"{k!r} is not a Find Me session key (findme/<session>/<kind>/...)")
    if not _SESSION_RE.match(parts[1]):
        raise BusError(f"session id {parts[1]!r} in key {k!r} is not valid")
    return Key(parts[1], parts[2], tuple(parts[3:]))


# ---------------------------------------------------------------------------------- config
@dataclass(frozen=True)
class BusConfig:
    """How a process joins the bus.

    mode: "peer" (default: in-process, or linked peers), "client" (through a router: the
        multi-process deployment; with multicast scouting off, peers do not route through a
        router) or "router".
    listen / connect: Zenoh endpoints, e.g. ``tcp/127.0.0.1:7447``; none = in-process only.
    tls: optional dict with ``root_ca_certificate``, ``listen_certificate``,
        ``listen_private_key`` (paths) for ``tls/...`` endpoints.
    user, password: optional credentials (transport/auth/usrpwd).
    extra: further Zenoh config as {json5 path: value}.
    """

    mode: str = "peer"
    listen: tuple[str, ...] = ()
    connect: tuple[str, ...] = ()
    tls: dict | None = None
    user: str | None = None
    password: str | None = None
    lease_ms: int = 1000
    connect_timeout_ms: int = 30000   # a client waits this long for its router to come up
    extra: dict = field(default_factory=dict)

    def zenoh(self) -> zenoh.Config:
        if self.mode not in ("peer", "client", "router"):
            raise BusError(f"bus mode must be peer, client or router, got {self.mode!r}")
        c = zenoh.Config()
        ins = c.insert_json5
        ins("mode", json.dumps(self.mode))
        ins("scouting/multicast/enabled", "false")
        ins("listen/endpoints", json.dumps(list(self.listen)))
        ins("connect/endpoints", json.dumps(list(self.connect)))
        if self.connect:
            # whole objects: setting one sub-key fails with "unknown key"
            ins("connect/retry", json.dumps({"period_init_ms": 200, "period_max_ms": 500,
                                             "period_increase_factor": 2.0}))
            ins("connect/timeout_ms", json.dumps({"router": -1, "peer": -1,
                                                  "client": int(self.connect_timeout_ms)}))
        ins("transport/link/tx/lease", str(int(self.lease_ms)))
        if self.tls:
            for k, v in self.tls.items():
                ins(f"transport/link/tls/{k}", json.dumps(v))
        if self.user is not None:
            ins("transport/auth/usrpwd/user", json.dumps(self.user))
            ins("transport/auth/usrpwd/password", json.dumps(self.password or ""))
        for k, v in self.extra.items():
            ins(k, json.dumps(v))
        return c


def zenoh_reason(e: Exception) -> str:
    """A Zenoh error's text without the Rust source location it ends with."""
    return re.sub(r"\s+at \S+\.rs:\d+\.?\s*$", "", str(e)).strip()


def open_session(cfg: BusConfig = BusConfig()) -> zenoh.Session:
    try:
        return zenoh.open(cfg.zenoh())
    except zenoh.ZError as e:
        where = ", ".join(cfg.connect or cfg.listen) or "in-process"
        reason = zenoh_reason(e)
        if cfg.connect and "Timeout" in reason:
            reason = (f"no router answered within {cfg.connect_timeout_ms / 1000:g} s (is it "
                      "running and reachable? for tls/ endpoints: the CA, the certificate's "
                      "host names and the password)")
        raise BusError(f"cannot open the Zenoh session ({cfg.mode}, {where}): {reason}") from None


# ---------------------------------------------------------------------------------- publish
def put(session: zenoh.Session, k: str, payload: bytes,
        max_bytes: int = MAX_MESSAGE_BYTES) -> None:
    """Reliable put: BLOCK congestion control, refused (BusError) above ``max_bytes``."""
    if len(payload) > max_bytes:
        raise BusError(f"message for {k} is {len(payload) / 1e6:.1f} MB, over the "
                       f"{max_bytes / 1e6:.0f} MB limit; it was not sent")
    session.put(k, payload, congestion_control=zenoh.CongestionControl.BLOCK,
                encoding=zenoh.Encoding.APPLICATION_PROTOBUF)


def fetch(session: zenoh.Session, key: str, timeout: float = 2.0,
          cancel: zenoh.CancellationToken | None = None) -> bytes | None:
    """The payload of the first reply to a ``get`` of ``key``, or None. ``cancel``: a
    token whose ``cancel()`` ends the wait at once (raises ``zenoh.ZError``)."""
    for reply in session.get(key, timeout=timeout, cancellation_token=cancel):
        if reply.ok is not None:
            return reply.ok.payload.to_bytes()
    return None


def get_all(session: zenoh.Session, selector: str, timeout: float = 5.0,
            payload: bytes | None = None,
            cancel: zenoh.CancellationToken | None = None) -> list[tuple[str, bytes]]:
    """Every reply (key, payload) to ``selector`` from every matching queryable: target ALL
    and no consolidation (Zenoh would otherwise keep one reply per key, e.g. one Error of
    many on ``findme/<s>/error``). Error replies are left out. ``cancel``: as ``fetch``."""
    out = []
    for r in session.get(selector, target=zenoh.QueryTarget.ALL, timeout=timeout,
                         consolidation=zenoh.ConsolidationMode.NONE, payload=payload,
                         cancellation_token=cancel):
        if r.ok is not None:
            out.append((str(r.ok.key_expr), r.ok.payload.to_bytes()))
    return out


def wait_alive(session: zenoh.Session, name: str, timeout: float = 60.0) -> None:
    """Until a liveliness token of service ``name`` is on the bus (no polling: a liveliness
    subscriber with history signals it).

    Raises:
        BusError: none appeared within ``timeout`` seconds.
    """
    ev = threading.Event()
    sub = session.liveliness().declare_subscriber(
        f"{SERVICES}/{name}/*", lambda s: s.kind == zenoh.SampleKind.PUT and ev.set(),
        history=True)
    try:
        if not ev.wait(timeout):
            raise BusError(f"no {name} service appeared on the bus within {timeout:.0f} s")
    finally:
        sub.undeclare()
