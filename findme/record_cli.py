"""``findme recover | view | replay | regress``: working with recorded sessions (MCAP).

* ``recover BROKEN.mcap -o FIXED.mcap``: salvage a recording whose recorder died.
* ``view SESSION.mcap``: the session in Rerun (a viewer, or ``SESSION.rrd`` beside it);
  ``view --live``: every session on the bus as it happens.
* ``replay SESSION.mcap``: put a recording back on the bus so the services run on it again.
* ``regress SESSION.mcap``: run its frames (and its selections) through the current
  services and compare every result with the recorded one; exit 1 on a difference.
"""

from __future__ import annotations

import math
import threading
import time
from collections import Counter, defaultdict
from dataclasses import dataclass, field
from pathlib import Path

import zenoh

import schemas
from findme_core.errors import InputError
from services import bus
from services.recorder import (Recorded, RecordingError, read_recording, recording_session,
                               recover)

INPUT_KINDS = ("frame", "selection")
ODOMETRY_KINDS = ("motion", "pose", "trajectory")


def register(sub) -> None:
    from .deploy import _bus_args

    r = sub.add_parser("recover", help="salvage a recording whose recorder died (no summary)")
    r.add_argument("recording", metavar="FILE.mcap")
    r.add_argument("-o", "--output", required=True, metavar="OUT.mcap")
    r.set_defaults(func=cmd_recover)

    v = sub.add_parser("view", help="show a recorded session (or the live bus) in Rerun")
    v.add_argument("recording", nargs="?", metavar="SESSION.mcap")
    where = v.add_mutually_exclusive_group()
    where.add_argument("--rrd", nargs="?", const="", metavar="OUT.rrd",
                       help="write a Rerun file (default: SESSION.rrd beside the MCAP; the "
                            "default when there is no display)")
    where.add_argument("--spawn", action="store_true", help="start a native Rerun viewer")
    where.add_argument("--web", action="store_true", help="start the Rerun web viewer")
    where.add_argument("--connect-viewer", metavar="URL",
                       help="send to a running viewer, e.g. rerun+http://127.0.0.1:9876/proxy")
    v.add_argument("--bind", default="127.0.0.1",
                   help="address of the viewer servers this starts (default 127.0.0.1: this "
                        "machine only)")
    v.add_argument("--port", type=int, help="gRPC port of the viewer this starts")
    v.add_argument("--live", action="store_true",
                   help="show every session on the bus as it happens (joins like serve)")
    v.add_argument("--out", default="recordings", help="--live without a viewer: .rrd folder")
    _bus_args(v)
    v.set_defaults(func=cmd_view)

    p = sub.add_parser("replay", help="republish a recording onto the bus")
    p.add_argument("recording", metavar="SESSION.mcap")
    speed = p.add_mutually_exclusive_group()
    speed.add_argument("--rate", type=float, default=1.0,
                       help="speed relative to the recording (default 1.0 = real time)")
    speed.add_argument("--max", action="store_true", help="as fast as the bus takes it")
    p.add_argument("--keys", choices=("inputs", "frames", "all"), default="inputs",
                   help="inputs (default): frames, the recorded selections (the user's "
                        "choices: run no selection service beside) and measurements, so the "
                        "running services compute the rest (a selection waits for its "
                        "hypotheses, a measurement for its scene); frames: frames only; "
                        "all: every recorded key as it was (e.g. for a viewer or recorder)")
    p.add_argument("--session", help="publish under this session id instead")
    p.add_argument("--wait-for", action="append", default=[], metavar="SERVICE",
                   help="start once these services are alive")
    p.add_argument("--timeout", type=float, default=60.0,
                   help="seconds to wait for hypotheses / scenes before going on")
    _bus_args(p)
    p.set_defaults(func=cmd_replay)

    g = sub.add_parser("regress", help="re-run a recording through the current services and "
                                       "compare every result (exit 1 on a difference)")
    g.add_argument("recording", metavar="SESSION.mcap")
    g.add_argument("--method", help="hypotheses method (default: the recording's)")
    g.add_argument("--max", type=int, default=10, help="hypotheses per photo (default 10)")
    g.add_argument("--timeout", type=float, default=120.0,
                   help="seconds to wait for each result (default 120)")
    g.add_argument("--json", action="store_true", help="the differences as JSON")
    g.set_defaults(func=cmd_regress)


# ------------------------------------------------------------------------------ recover
def cmd_recover(args) -> int:
    src, dst = Path(args.recording), Path(args.output)
    s = recover(src, dst)
    what = (f"{s.messages} messages ({s.bus_messages} bus messages, "
            f"{s.messages - s.bus_messages} view messages) in {s.chunks} chunks")
    if s.complete:
        print(f"{src} was complete: copied {what} to {dst}")
    else:
        print(f"recovered {what} from {src} into {dst}; dropped the last {s.dropped_bytes} "
              f"bytes (an unfinished chunk or record: {s.reason})")
    return 0


# ------------------------------------------------------------------------------ view
def cmd_view(args) -> int:
    from services.viewer import Sink, has_display
    if args.live:
        return _view_live(args)
    if not args.recording:
        raise InputError("view needs a recording (SESSION.mcap) or --live")
    src = Path(args.recording)
    recs = read_recording(src)
    if args.connect_viewer:
        sink = Sink("connect", url=args.connect_viewer)
    elif args.spawn or args.web:
        sink = Sink("spawn" if args.spawn else "web", bind=args.bind, port=args.port)
    elif args.rrd is not None or not has_display():
        sink = Sink("rrd", path=args.rrd or str(src.with_suffix(".rrd")))
    else:
        sink = Sink("spawn", bind=args.bind, port=args.port)
    where, shown = view_recording(recs, sink)
    print(f"{src}: {shown} messages shown -> {where}")
    if sink.mode == "web":   # the web viewer lives as long as this command: until Ctrl-C
        from services.registry import wait_for_signal
        print("serving the web viewer; Ctrl-C to stop", flush=True)
        try:
            wait_for_signal()
        finally:
            sink.stop()
    return 0


def view_recording(recs: list[Recorded], sink) -> tuple[str, int]:
    """Log a recording's bus messages through the Rerun adapters into ``sink``."""
    from findme.viz import SessionView, blueprint
    from services.viewer import new_recording
    if not recs:
        raise RecordingError("the recording holds no Find Me messages")
    session = bus.parse_key(recs[0].key).session
    photos = {bus.parse_key(r.key).index() for r in recs if bus.parse_key(r.key).kind == "frame"}
    rec = new_recording(session)
    where = sink.attach(rec, session, blueprint(photos))
    view = SessionView(rec)
    view.photos = set(photos)                      # the default blueprint already has them
    view._blueprint_for = tuple(sorted(photos))
    shown = 0
    for r in recs:
        try:
            msg = r.message()
        except Exception:  # noqa: BLE001 - a malformed recorded payload: nothing to draw
            continue
        if msg is None:
            continue
        try:
            shown += view.log(msg, r.log_time)
        except InputError:
            continue
    rec.flush()
    rec.disconnect()
    return where, shown


def _view_live(args) -> int:
    from services.registry import wait_for_signal
    from services.runtime import Service
    from services.viewer import Sink, ViewerHandler, has_display

    from .deploy import _logging, _open
    _logging()
    if args.connect_viewer:
        sink = Sink("connect", url=args.connect_viewer)
    elif args.spawn or args.web or (has_display() and args.rrd is None):
        sink = Sink("web" if args.web else "spawn", bind=args.bind, port=args.port)
    else:
        sink = Sink("rrd", path=args.rrd or args.out)
    session = _open(args)
    svc = Service(ViewerHandler(sink), session).start()
    try:
        wait_for_signal()
    finally:
        svc.stop()
        session.close()
        sink.stop()
    return 0


# ------------------------------------------------------------------------------ the bus side
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
    """The MeasureRequest a recorded MeasureReply answered (its pixels, in order)."""
    req = schemas.MeasureRequest(session=reply.session, index=reply.index)
    req.pixels.extend(schemas.Pixel(u=p.pixel.u, v=p.pixel.v) for p in reply.points)
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


# ------------------------------------------------------------------------------ replay
def cmd_replay(args) -> int:
    from services.bus import wait_alive

    from .deploy import _logging, _open
    _logging()
    if args.rate <= 0 or not math.isfinite(args.rate):
        raise InputError(f"--rate must be a positive number, got {args.rate}")
    recs = read_recording(args.recording)
    if not recs:
        raise RecordingError(f"{args.recording}: no Find Me messages to replay")
    if args.session:
        if not schemas.is_valid_session(args.session):
            raise InputError(f"--session {args.session!r} is not a valid session id")
        recs = [rename_session(r, args.session) for r in recs]
    session_id = bus.parse_key(recs[0].key).session
    session = _open(args)
    try:
        for name in args.wait_for:
            wait_alive(session, name)
        n = replay(session, recs, keys=args.keys, rate=None if args.max else args.rate,
                   timeout=args.timeout, log=print)
    finally:
        session.close()
    print(f"replayed {n} messages of session {session_id} from {args.recording}")
    return 0


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


# ------------------------------------------------------------------------------ regress
#: Tolerances of ``findme regress`` (also printed with every failure).
TOL_PX = 1.0                      # a polyline vertex / pixel may move this far (Euclidean)
TOL_M = 1e-3                      # metres: fields ending _m, 3D points (Euclidean)
TOL_RAD = math.radians(0.01)      # radians: fields ending _rad (0.01 deg)
TOL_SCORE = 1e-4                  # hypothesis score and support (absolute)
TOL_FLOAT = 1e-6                  # any other float (relative to max(1, |value|))
#: Not compared: clocks and who answered.
IGNORED = {"time_ns", "timing_ms", "service", "schema"}
TOLERANCES = (f"polyline vertices and pixels within {TOL_PX:g} px; 3D points and lengths "
              f"(_m) within {TOL_M * 1e3:g} mm; angles (_rad) within 0.01 deg; score and "
              f"support within {TOL_SCORE:g}; other numbers within {TOL_FLOAT:g} relative; "
              "integers, enums and text exact; times not compared")


def _f(x: float) -> str:
    return f"{x:.6g}"


def _diff_scalar(fd, a, b, path: str, parent: str) -> str | None:
    from google.protobuf.descriptor import FieldDescriptor as FD
    if fd.type in (FD.TYPE_DOUBLE, FD.TYPE_FLOAT):
        name = fd.name
        if name.endswith("_m"):
            tol, unit, scale = TOL_M, "mm", 1e3
        elif name.endswith("_rad"):
            tol, unit, scale = TOL_RAD, "deg", math.degrees(1.0)
        elif name in ("score", "support"):
            tol, unit, scale = TOL_SCORE, "", 1.0
        else:
            tol, unit, scale = TOL_FLOAT * max(1.0, abs(a)), "", 1.0
        if math.isnan(a) and math.isnan(b):
            return None
        d = abs(a - b)
        if not d <= tol:
            return (f"{path}: {_f(a)} recorded, {_f(b)} now (off by {_f(d * scale)}"
                    f"{' ' + unit if unit else ''} > {_f(tol * scale)}{' ' + unit if unit else ''})")
        return None
    if a != b:
        if fd.enum_type is not None:
            a, b = fd.enum_type.values_by_number.get(a, a), fd.enum_type.values_by_number.get(b, b)
            a, b = getattr(a, "name", a), getattr(b, "name", b)
        return f"{path}: {a!r} recorded, {b!r} now"
    return None


def _diff_value(fd, a, b, path: str) -> list[str]:
    from google.protobuf.descriptor import FieldDescriptor as FD
    if fd.type != FD.TYPE_MESSAGE:
        d = _diff_scalar(fd, a, b, path, "")
        return [d] if d else []
    t = fd.message_type.full_name
    if t == "findme.v1.Pixel":
        d = math.hypot(a.u - b.u, a.v - b.v)
        if not d <= TOL_PX:
            return [f"{path}: ({a.u:.2f}, {a.v:.2f}) recorded, ({b.u:.2f}, {b.v:.2f}) now "
                    f"(moved {d:.2f} px > {TOL_PX:g} px)"]
        return []
    if t == "findme.v1.Vec3" and fd.name == "xyz":
        d = math.dist((a.x, a.y, a.z), (b.x, b.y, b.z))
        if not d <= TOL_M:
            return [f"{path}: ({a.x:.4f}, {a.y:.4f}, {a.z:.4f}) recorded, ({b.x:.4f}, {b.y:.4f}, "
                    f"{b.z:.4f}) now (moved {d * 1e3:.2f} mm > {TOL_M * 1e3:g} mm)"]
        return []
    return diff_messages(a, b, path)


def diff_messages(a, b, path: str = "") -> list[str]:
    """Readable differences between a recorded and a current message beyond the tolerances."""
    out: list[str] = []
    for fd in a.DESCRIPTOR.fields:
        if fd.name in IGNORED:
            continue
        p = f"{path}.{fd.name}" if path else fd.name
        if fd.is_repeated:
            if fd.message_type is not None and fd.message_type.GetOptions().map_entry:
                da, db = dict(getattr(a, fd.name)), dict(getattr(b, fd.name))
                if sorted(da) != sorted(db):
                    out.append(f"{p}: keys {sorted(da)} recorded, {sorted(db)} now")
                continue
            va, vb = list(getattr(a, fd.name)), list(getattr(b, fd.name))
            if len(va) != len(vb):
                out.append(f"{p}: {len(va)} recorded, {len(vb)} now")
            for i, (x, y) in enumerate(zip(va, vb)):
                out.extend(_diff_value(fd, x, y, f"{p}[{i}]"))
            continue
        if fd.has_presence:
            ha, hb = a.HasField(fd.name), b.HasField(fd.name)
            if ha != hb:
                out.append(f"{p}: {'set' if ha else 'unset'} recorded, {'set' if hb else 'unset'} now")
                continue
            if not ha:
                continue
        out.extend(_diff_value(fd, getattr(a, fd.name), getattr(b, fd.name), p))
    return out


@dataclass
class Regression:
    """The outcome of ``regress``: what was compared and every difference found."""

    recording: str
    session: str
    compared: int = 0
    differences: dict[str, list[str]] = field(default_factory=dict)
    notes: list[str] = field(default_factory=list)

    @property
    def ok(self) -> bool:
        return not self.differences

    def report(self) -> str:
        lines = [f"regress {self.recording} (session {self.session}): {self.compared} results "
                 f"compared, {len(self.differences)} differ"]
        lines += [f"  note: {n}" for n in self.notes]
        for key, diffs in self.differences.items():
            lines.append(f"  {key}:")
            lines += [f"    {d}" for d in diffs[:12]]
            if len(diffs) > 12:
                lines.append(f"    ... and {len(diffs) - 12} more")
        lines.append(("PASS" if self.ok else "FAIL") + f" (tolerances: {TOLERANCES})")
        return "\n".join(lines)


def _short(key: str, session: str) -> str:
    p = f"{bus.ROOT}/{session}/"
    return key[len(p):] if key.startswith(p) else key


def _error_sig(payload: bytes) -> tuple:
    try:
        e = schemas.decode(schemas.Error, payload, check=False)
        return (e.key, schemas.ErrorCode.Name(e.code), e.message)
    except Exception:  # noqa: BLE001
        return ("?", "?", payload[:40].hex())


def regress(path, *, method: str | None = None, max_n: int = 10, timeout: float = 120.0,
            handlers=None) -> Regression:
    """Replay a recording's frames, selections and measurements through the current services
    (embedded, one in-process Zenoh session, as ``findme run``) and compare every result
    with the recorded one. ``handlers`` replaces the services (tests)."""
    from services.runtime import Group

    recs = read_recording(path)
    session_id = recording_session(path)
    out = Regression(str(path), session_id)
    recs = [r for r in recs if bus.parse_key(r.key).session == session_id]
    expected: dict[str, list[bytes]] = defaultdict(list)
    for r in recs:
        kind = bus.parse_key(r.key).kind
        if kind not in INPUT_KINDS and kind != "measured":
            expected[r.key].append(r.payload)
    kinds = {bus.parse_key(k).kind for k in expected}
    if handlers is None:
        handlers = _handlers(recs, kinds, method, max_n, out.notes)

    session = bus.open_session(bus.BusConfig())   # peer, no endpoints: in-process only
    group = Group(session)
    watch = Watch(session, session_id)
    measured_now: list[tuple[str, bytes | None, str]] = []
    try:
        for h in handlers:
            group.add(h)
        source = Source(session, session_id)
        for r in recs:
            k = bus.parse_key(r.key)
            if k.kind == "frame":
                source.put(r.key, r.payload)
            elif k.kind == "selection":
                need = bus.key(session_id, "hypotheses", *k.parts)
                wait_result(group, watch, lambda c, need=need: c[need] > 0, timeout)
                source.put(r.key, r.payload)
            elif k.kind == "measured":
                need = bus.key(session_id, "scene", *k.parts)
                wait_result(group, watch, lambda c, need=need: c[need] > 0, timeout)
                rep = schemas.decode(schemas.MeasureReply, r.payload, check=False)
                payload, err = ask_measure(session, session_id, measure_request(rep), timeout)
                measured_now.append((r.key, payload, err))
        # every recorded result as often as it was recorded (or quiet: it will not come);
        # then quiet, so that extra results are seen too
        wait_result(group, watch, lambda c: all(c[k] >= len(v) for k, v in expected.items()),
                    timeout)
        wait_result(group, watch, lambda c: False, timeout)
        source.close()
    finally:
        watch.close()
        group.stop()
        session.close()

    got: dict[str, list[bytes]] = defaultdict(list)
    for k, payload in watch.got:
        if bus.parse_key(k).kind not in INPUT_KINDS + ("measured",):
            got[k].append(payload)
    for key in sorted(set(expected) | set(got)):
        short = _short(key, session_id)
        rec_list, now_list = expected.get(key, []), got.get(key, [])
        out.compared += 1
        if bus.parse_key(key).kind == "error":   # a multiset of errors
            a, b = Counter(map(_error_sig, rec_list)), Counter(map(_error_sig, now_list))
            diffs = [f"recorded, not now: {e[0]}: {e[1]}: {e[2]}" for e in (a - b).elements()]
            diffs += [f"now, not recorded: {e[0]}: {e[1]}: {e[2]}" for e in (b - a).elements()]
            if diffs:
                out.differences[short] = diffs
            continue
        if not now_list:
            out.differences[short] = [f"missing: recorded {len(rec_list)} message(s), none now"]
            continue
        if not rec_list:
            out.differences[short] = [f"new: {len(now_list)} message(s) now, none recorded"]
            continue
        diffs = []
        if len(rec_list) != len(now_list):
            diffs.append(f"published {len(rec_list)} time(s) when recorded, {len(now_list)} now "
                         "(comparing the last)")
        diffs += _compare_payloads(rec_list[-1], now_list[-1])
        if diffs:
            out.differences[short] = diffs
    recorded_measures = [r for r in recs if bus.parse_key(r.key).kind == "measured"]
    for i, (r, (key, payload, err)) in enumerate(zip(recorded_measures, measured_now)):
        short = f"{_short(key, session_id)} (measurement {i + 1})"
        out.compared += 1
        if payload is None:
            out.differences[short] = [f"no answer now: {err}"]
            continue
        diffs = _compare_payloads(r.payload, payload)
        if diffs:
            out.differences[short] = diffs
    return out


def _compare_payloads(recorded: bytes, now: bytes) -> list[str]:
    try:
        a = schemas.decode_any(recorded, check=False)
    except Exception as e:  # noqa: BLE001
        return [f"the recorded payload does not decode ({e})"] if recorded != now else []
    try:
        b = schemas.decode_any(now, check=False)
    except Exception as e:  # noqa: BLE001
        return [f"the current payload does not decode ({e})"]
    if type(a) is not type(b):
        return [f"a {a.DESCRIPTOR.full_name} recorded, a {b.DESCRIPTOR.full_name} now"]
    return diff_messages(a, b)


def wait_result(group, watch: Watch, pred, timeout: float, step: float = 0.05) -> bool:
    """Until ``pred(counts)`` holds (True), or the bus has gone quiet without it (False):
    every service idle and nothing new arriving for three steps in a row, so it will not
    come. ``timeout`` caps the wait. With ``pred`` never true this waits for quiet."""
    deadline = time.monotonic() + timeout
    last, stable = None, 0
    while True:
        if watch.wait(pred, step):
            return True
        with watch.cv:
            n = len(watch.got)
        idle = all(s.idle.is_set() for s in group.services)
        state = (n, tuple(s.counters.frames_in for s in group.services))
        stable = stable + 1 if (idle and state == last) else 0
        last = state
        if stable >= 3 or time.monotonic() > deadline:
            with watch.cv:
                return bool(pred(watch.count))


def _handlers(recs, kinds, method, max_n, notes) -> list:
    from services.hypotheses import HypothesesHandler
    from services.measurement import MeasurementHandler
    if method is None:
        for r in recs:
            if bus.parse_key(r.key).kind == "hypotheses":
                m = schemas.decode(schemas.HypothesisSet, r.payload, check=False).method
                method = m.split("/", 1)[0] if m else None
                break
    hs = [HypothesesHandler(method or "findme", max_n), MeasurementHandler()]
    if kinds & set(ODOMETRY_KINDS):
        try:
            from services.odometry import OdometryHandler
            hs.append(OdometryHandler())
        except ImportError:
            notes.append("the recording has odometry results but this build has no odometry "
                         "service")
    else:
        notes.append("odometry not run: the recording has no motion, pose or trajectory")
    return hs


def cmd_regress(args) -> int:
    import logging

    from .deploy import _logging
    _logging(logging.ERROR)
    r = regress(args.recording, method=args.method, max_n=args.max, timeout=args.timeout)
    if args.json:
        import json
        print(json.dumps({"recording": r.recording, "session": r.session, "ok": r.ok,
                          "compared": r.compared, "differences": r.differences,
                          "notes": r.notes, "tolerances": TOLERANCES}, indent=1))
    else:
        print(r.report())
    return 0 if r.ok else 1
