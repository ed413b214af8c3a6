"""Putting a recorded session back on the bus: ``replay`` (``findme replay``) and the bus
side it shares with ``findme regress`` (``Watch``, ``Source``, ``ask_measure``).

Messages go out in their recorded order on the keys they were recorded on, paced by their
log times (ns since the epoch, divided by ``rate``). A recorded selection waits for its
hypotheses, a recorded measurement is asked again of the measurement service once its scene
is on the bus (its pixels as recorded: bus convention, (0, 0) at the centre of the top-left
pixel). ``rename_session`` returns new messages; recorded ones are never changed.
"""

from __future__ import annotations

import threading
import time
from collections import Counter

import zenoh

import schemas
from services.runtime import bus
from services.recording.mcap_reader import Recorded

#: The kinds of key a session's inputs go on (what ``Source`` answers ``get`` for).
INPUT_KINDS = ("frame", "selection")


class Watch:
    """Every message of one session as it arrives (key, payload), with a condition to wait on."""

    def __init__(self, session: zenoh.Session, session_id: str):
        self.cv = threading.Condition()
        self.got: list[tuple[str, bytes]] = []
        self.count: Counter = Counter()
        self.sub = session.declare_subscriber(f"{bus.ROOT}/{session_id}/**", self._cb)

    def _cb(self, sample: zenoh.Sample) -> None:
        if sample.kind != zenoh.SampleKind.PUT:
            return
        k = str(sample.key_expr)
        with self.cv:
            self.got.append((k, sample.payload.to_bytes()))
            self.count[k] += 1
            self.cv.notify_all()

    def wait(self, pred, timeout: float) -> bool:
        with self.cv:
            return self.cv.wait_for(lambda: pred(self.count), timeout)

    def close(self) -> None:
        self.sub.undeclare()


class Source:
    """Answers ``get`` for the frames and selections it published (as a capture service
    would), so a service that starts late or missed one can fetch it."""

    def __init__(self, session: zenoh.Session, session_id: str):
        self.session = session
        self.store: dict[str, bytes] = {}
        self.lock = threading.Lock()
        self.decls = [session.declare_queryable(f"{bus.ROOT}/{session_id}/{kind}/*", self._q)
                      for kind in INPUT_KINDS]

    def _q(self, query: zenoh.Query) -> None:
        want = zenoh.KeyExpr(str(query.key_expr))
        with self.lock:
            hits = [(k, v) for k, v in self.store.items() if want.intersects(zenoh.KeyExpr(k))]
        for k, v in hits:
            query.reply(k, v)

    def put(self, key: str, payload: bytes) -> None:
        if bus.parse_key(key).kind in INPUT_KINDS:
            with self.lock:
                self.store[key] = payload
        bus.put(self.session, key, payload)

    def close(self) -> None:
        for d in self.decls:
            d.undeclare()


def rename_session(r: Recorded, new: str) -> Recorded:
    """The same message under another session id (key, ``session`` fields, frame names)."""
    k = bus.parse_key(r.key)
    old = k.session
    key = bus.key(new, k.kind, *k.parts)
    payload = r.payload
    msg = None
    try:
        msg = r.message()
    except Exception:  # noqa: BLE001 - malformed: keep the bytes, change only the key
        pass
    if msg is not None:
        if getattr(msg, "session", None) == old:
            msg.session = new
        if msg.DESCRIPTOR.full_name == "findme.v1.Frame" and msg.image.frame_id.startswith(old + "/"):
            msg.image.frame_id = new + msg.image.frame_id[len(old):]
        if msg.DESCRIPTOR.full_name == "findme.v1.Error" and msg.key.startswith(f"{bus.ROOT}/{old}/"):
            msg.key = f"{bus.ROOT}/{new}/" + msg.key[len(bus.ROOT) + len(old) + 2:]
        payload = msg.SerializeToString(deterministic=True)
    return Recorded(key, r.topic, r.channel, r.schema, payload, r.log_time)


def measure_request(reply) -> object:
    """The MeasureRequest a recorded MeasureReply answered (its pixels, in order, and the
    surface said of each, if any was)."""
    req = schemas.MeasureRequest(session=reply.session, index=reply.index)
    req.pixels.extend(schemas.Pixel(u=p.pixel.u, v=p.pixel.v) for p in reply.points)
    if any(p.said for p in reply.points):
        req.said.extend(p.said for p in reply.points)
    return req


def ask_measure(session: zenoh.Session, session_id: str, req, timeout: float = 10.0):
    """(reply payload bytes, or None with an error text)."""
    for reply in session.get(bus.key(session_id, "measure"), payload=schemas.encode(req),
                             timeout=timeout):
        if reply.ok is not None:
            return reply.ok.payload.to_bytes(), ""
        try:
            err = schemas.decode(schemas.Error, reply.err.payload.to_bytes())
            return None, err.message
        except Exception:  # noqa: BLE001 - an error reply we cannot read
            return None, "the measurement service answered with an error"
    return None, f"no measurement service answered within {timeout:.0f} s"


def replay(session: zenoh.Session, recs: list[Recorded], *, keys: str = "inputs",
           rate: float | None = 1.0, timeout: float = 60.0, log=None) -> int:
    """Publish recorded messages in their recorded order, paced by their log times / rate
    (None: no pacing). With ``keys="inputs"`` a selection waits until its hypotheses are
    on the bus and a recorded measurement is asked again once its scene is (then published
    on ``measured/<n>`` like ``findme run`` does). Returns how many were published."""
    session_id = bus.parse_key(recs[0].key).session
    watch, source = Watch(session, session_id), Source(session, session_id)
    pace = threading.Event()
    t0_rec, t0 = recs[0].log_time, time.monotonic()
    sent = 0
    try:
        for r in recs:
            k = bus.parse_key(r.key)
            if keys != "all" and k.kind not in (("frame",) if keys == "frames" else
                                                ("frame", "selection", "measured")):
                continue
            if rate is not None:
                due = t0 + (r.log_time - t0_rec) / 1e9 / rate
                pace.wait(max(0.0, due - time.monotonic()))
            if keys == "inputs" and k.kind in ("selection", "measured"):
                need = bus.key(session_id, "hypotheses" if k.kind == "selection" else "scene",
                               *k.parts)
                if not watch.wait(lambda c, need=need: c[need] > 0, timeout) and log:
                    log(f"replay: {need} did not appear within {timeout:.0f} s; going on")
                if k.kind == "measured":
                    rep = schemas.decode(schemas.MeasureReply, r.payload, check=False)
                    payload, err = ask_measure(session, session_id, measure_request(rep))
                    if payload is None:
                        if log:
                            log(f"replay: measure photo {rep.index}: {err}")
                        continue
                    source.put(r.key, payload)
                    sent += 1
                    continue
            source.put(r.key, r.payload)
            sent += 1
    finally:
        watch.close()
        source.close()
    return sent
