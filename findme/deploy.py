"""``findme run | serve | router | status``: the services on a Zenoh bus.

* ``run``: every service in this process on one Zenoh session (the default deployment):
  photos (default: the bundled example) -> hypotheses -> selection -> scenes, motion and
  trajectory, printed as they arrive; then a measurement query.
* ``serve SERVICE``: one service in this process, joining a bus (``--connect``/``--listen``).
* ``router``: a Zenoh router for services and phones on other processes / machines.
* ``status``: which services are alive and their counters.
"""

from __future__ import annotations

import logging
import sys
import threading
import time
import uuid
from importlib import resources
from pathlib import Path

import zenoh

import schemas
from findme_core.errors import BusError, InputError
from services.runtime import bus
from services.pipeline.capture import CaptureHandler, Lens, publish_frames, sources
from services.runtime.registry import (add_service_args, make_handler, service_names,
                                      service_options, wait_for_signal)
from services.runtime.service import Group, Service

from .options import add_camera_args, floats

PIPELINE = ("hypotheses", "selection", "measurement", "odometry")


def _bus_args(p, default_listen=()):
    p.add_argument("--connect", action="append", default=[], metavar="ENDPOINT",
                   help="Zenoh endpoint to connect to, e.g. tcp/127.0.0.1:7447 (repeatable)")
    p.add_argument("--listen", action="append", default=list(default_listen), metavar="ENDPOINT",
                   help="Zenoh endpoint to listen on (repeatable)")
    p.add_argument("--mode", choices=("peer", "client"),
                   help="Zenoh mode (default: client of the router with --connect, else peer)")
    p.add_argument("--config", metavar="FILE.json5", help="a full Zenoh configuration file")


def register(sub) -> None:
    r = sub.add_parser("run", help="all services in one process on the example or your photos",
                       description=__doc__)
    r.add_argument("photos", nargs="*", help="image files, folders, a video or camera:N "
                                             "(default: the bundled example)")
    r.add_argument("--session", help="session id (default: a new one)")
    add_camera_args(r)
    r.add_argument("--camera-height", type=float, metavar="M")
    r.add_argument("--measure", action="append", metavar="U,V",
                   help="pixels of photo 0 to measure at the end (repeatable)")
    add_service_args(r)
    r.add_argument("--no-record", action="store_true",
                   help="do not record the session (default: <out>/<session>.mcap)")
    _bus_args(r)
    r.set_defaults(func=cmd_run, out="findme-run")

    s = sub.add_parser("serve", help="run one service, joining a bus")
    s.add_argument("service", choices=service_names())
    s.add_argument("photos", nargs="*", help="capture: image files, folders, a video or camera:N")
    s.add_argument("--session", help="capture: session id")
    s.add_argument("--instance", help="instance id (default: random)")
    add_camera_args(s)
    s.add_argument("--camera-height", type=float, metavar="M")
    s.add_argument("--wait-for", action="append", default=[], metavar="SERVICE",
                   help="capture: publish only once these services are alive")
    add_service_args(s)
    _bus_args(s)
    s.set_defaults(func=cmd_serve)

    t = sub.add_parser("router", help="a Zenoh router for services on other processes/machines")
    _bus_args(t, default_listen=())
    t.set_defaults(func=cmd_router)

    st = sub.add_parser("status", help="which services are alive, with their counters")
    _bus_args(st)
    st.add_argument("--json", action="store_true")
    st.set_defaults(func=cmd_status)


def bus_config(args, mode: str | None = None) -> bus.BusConfig:
    mode = mode or args.mode or ("client" if args.connect else "peer")
    if getattr(args, "config", None):
        return bus.BusConfig(mode=mode, extra={"__file__": args.config})
    return bus.BusConfig(mode=mode, listen=tuple(args.listen), connect=tuple(args.connect))


def _open(args, mode=None) -> zenoh.Session:
    cfg = bus_config(args, mode)
    if "__file__" in cfg.extra:
        try:
            return zenoh.open(zenoh.Config.from_file(cfg.extra["__file__"]))
        except zenoh.ZError as e:
            raise BusError(f"cannot open the Zenoh session from {cfg.extra['__file__']}: {e}") from None
    return bus.open_session(cfg)


def _lens(args) -> Lens:
    return Lens(intrinsics=floats(args.intrinsics, 4, "--intrinsics") if args.intrinsics else None,
                hfov_deg=args.hfov,
                gravity=floats(args.gravity, 3, "--gravity") if args.gravity else None,
                camera_height_m=args.camera_height)


def _logging(level=logging.INFO):
    logging.basicConfig(level=level, format="%(asctime)s %(levelname)s %(name)s: %(message)s",
                        stream=sys.stderr)


# ------------------------------------------------------------------------------ run
class Printer:
    """Prints a session's results as they arrive on the bus."""

    def __init__(self, session: str, out=None):
        self.session, self.out = session, out or sys.stdout
        self.cv = threading.Condition()
        self.seen: dict[str, object] = {}

    def __call__(self, sample: zenoh.Sample) -> None:
        k = str(sample.key_expr)
        try:
            msg = schemas.decode_any(sample.payload.to_bytes())
        except Exception:  # noqa: BLE001 - a foreign payload: nothing to print
            return
        with self.cv:
            self.seen[k] = msg
            self.cv.notify_all()

    ORDER = ("frame", "hypotheses", "selection", "scene", "motion", "pose")

    def report(self, n: int) -> None:
        """Print photo n's results in pipeline order (they arrive in any order)."""
        p = f"findme/{self.session}/"
        with self.cv:
            items = list(self.seen.items())
        lines = []
        for kind in self.ORDER:
            for k, m in items:
                if (k.startswith(p + kind + "/") and k.endswith(f"/{n}")) or \
                        (kind == "frame" and type(m).__name__ == "Error" and k.endswith("/error")
                         and f"/{n}" in m.key):
                    line = self.describe(k, m)
                    if line and line not in lines:
                        lines.append(line)
        print("\n".join(lines), file=self.out, flush=True)

    def wait(self, done, timeout: float) -> bool:
        """Until ``done(seen)`` is true (results arrived), or the timeout."""
        with self.cv:
            return self.cv.wait_for(lambda: done(self.seen), timeout)

    def photo_done(self, n: int, odometry: bool):
        """Photo n's results are all in: its scene (or an error about it), and its pose or
        motion when odometry runs."""
        def errors_about(seen, what):
            return any(type(m).__name__ == "Error" and f"/{what}/{n}" in m.key for m in seen.values())

        def done(seen):
            p = f"findme/{self.session}/"
            scene = (p + f"scene/{n}" in seen and p + f"hypotheses/{n}" in seen) or \
                errors_about(seen, "frame") or \
                errors_about(seen, "hypotheses") or errors_about(seen, "selection")
            if not odometry or not scene:
                return scene
            return p + f"pose/{n}" in seen or any(k.startswith(p + "motion/") and
                                                   k.endswith(f"/{n}") for k in seen)
        return done

    @staticmethod
    def describe(k: str, m) -> str | None:
        name = type(m).__name__
        if name == "Frame":
            return f"photo {m.index}: {m.device or 'frame'} ({len(m.image.data) // 1024} kB)"
        if name == "HypothesisSet":
            t = sum(m.timing_ms.values())
            return (f"photo {m.index}: {len(m.hypotheses)} hypotheses in {t:.0f} ms"
                    + (f" ({m.reason})" if m.reason else ""))
        if name == "Selection":
            return f"photo {m.index}: hypothesis {m.rank} selected ({'auto' if m.by == 2 else 'user'})"
        if name == "Scene":
            return f"photo {m.index}: scene ready (camera {m.camera_height_m:.2f} m" \
                   f"{'' if m.metric else ', up to scale'})"
        if name == "Motion":
            if m.error:
                return f"motion {m.index_a} -> {m.index_b}: no estimate: {m.error}"
            return (f"motion {m.index_a} -> {m.index_b}: x {m.x_m:+.3f} m, z {m.z_m:+.3f} m, yaw "
                    f"{__import__('math').degrees(m.yaw_rad):+.2f} deg ({m.inliers}/{m.matches} inliers)")
        if name == "Pose":
            return (f"photo {m.index}: at x {m.x_m:+.3f} m, z {m.z_m:+.3f} m, heading "
                    f"{__import__('math').degrees(m.yaw_rad):+.1f} deg from photo 0")
        if name == "Error":
            return f"error on {m.key}: {m.message}"
        return None


def _example_paths() -> list[str]:
    base = resources.files("findme") / "examples"
    return [str(base / "room_a.jpg"), str(base / "room_b.jpg")]


def cmd_run(args) -> int:
    _logging(logging.WARNING)
    session_id = args.session or f"run-{uuid.uuid4().hex[:6]}"
    photos = args.photos or _example_paths()
    Path(args.out).mkdir(parents=True, exist_ok=True)
    srcs = list(sources(photos))  # read and validate every photo before starting
    session = _open(args)
    group = Group(session)
    printer = Printer(session_id)
    sub = session.declare_subscriber(f"findme/{session_id}/**", printer)
    recorder = None
    try:
        if not args.no_record:  # first in, so stopped last: it records everything
            from services.recording.recorder import RecorderHandler
            recorder = group.add(RecorderHandler(args.out)).handler
        capture = group.add(CaptureHandler())
        names = []
        for name in PIPELINE:
            try:
                names.append(group.add(make_handler(name, args)).handler.name)
            except ImportError:  # a service whose module is not installed
                continue
        t0 = time.perf_counter()
        n = publish_frames(capture, session_id, srcs, _lens(args))
        for i in range(n):
            if not printer.wait(printer.photo_done(i, "odometry" in names), 600):
                raise BusError(f"no result for photo {i} within 10 minutes")
            printer.report(i)
        print(f"session {session_id}: {n} photos processed in {time.perf_counter() - t0:.2f} s")
        _measure(session, session_id, args, photos)
    finally:
        sub.undeclare()
        group.stop()
        session.close()
    if recorder is not None and recorder.path_of(session_id):
        print(f"recording: {recorder.path_of(session_id)}")
    return 0


def _measure(session, session_id, args, photos) -> None:
    pixels = [floats(p, 2, "--measure") for p in args.measure or []]
    if not pixels and not args.photos:  # the example: its ground-truth floor points
        import json
        meta = json.loads((resources.files("findme") / "examples" / "room_a.json").read_text())
        pixels = [tuple(q["px"]) for q in meta["ground_truth"]["floor_points"][1:3]]
    if not pixels:
        return
    req = schemas.MeasureRequest(session=session_id, index=0)
    req.pixels.extend(schemas.pixels_to_msg(pixels))
    for reply in session.get(bus.key(session_id, "measure"), payload=schemas.encode(req), timeout=10):
        if reply.ok is None:
            err = schemas.decode(schemas.Error, reply.err.payload.to_bytes())
            print(f"measure: {err.message}")
            continue
        rep = schemas.decode(schemas.MeasureReply, reply.ok.payload.to_bytes())
        bus.put(session, bus.key(session_id, "measured", rep.index), reply.ok.payload.to_bytes())  # for the record
        unit = "m" if rep.metric else "camera heights"
        for p in rep.points:
            where = (f"{schemas.Surface.Name(p.surface).split('_')[1].lower()} at "
                     f"({p.xyz.x:+.3f}, {p.xyz.y:+.3f}, {p.xyz.z:+.3f}) {unit} ± {p.sigma_m:.3f}"
                     if not p.error else p.error)
            print(f"measure photo 0 pixel ({p.pixel.u:g}, {p.pixel.v:g}): {where}")
        for d in rep.distances:
            if not d.error:
                print(f"distance {d.a + 1}-{d.b + 1}: {d.distance_m:.3f} {unit} ± {d.sigma_m:.3f}")
        if not args.photos:
            _example_truth(pixels)
        return


def _example_truth(pixels) -> None:
    """The bundled example is rendered: print its true motion and distance to compare."""
    import json
    import math
    base = resources.files("findme") / "examples"
    pair = json.loads((base / "pair.json").read_text())["motion"]
    pts = {tuple(q["px"]): q["xyz_m"] for q in
           json.loads((base / "room_a.json").read_text())["ground_truth"]["floor_points"]}
    d = math.dist(pts[tuple(pixels[0])], pts[tuple(pixels[1])])
    print(f"truth (the example is rendered): motion x {pair['x_m']:+.3f} m, z {pair['z_m']:+.3f} m,"
          f" yaw {pair['yaw_deg']:+.2f} deg; distance 1-2 {d:.3f} m")


# ------------------------------------------------------------------------------ serve
def cmd_serve(args) -> int:
    _logging()
    session = _open(args)
    svc = Service(make_handler(args.service, args), session, instance=args.instance,
                  **service_options(args)).start()
    try:
        if args.service == "capture":
            if not args.photos or not args.session:
                raise InputError("capture needs --session and at least one photo")
            for name in args.wait_for:
                bus.wait_alive(session, name)
            n = publish_frames(svc, args.session, sources(args.photos), _lens(args))
            logging.getLogger("findme.services").info("capture: published %d frames", n)
        wait_for_signal()
    finally:
        svc.stop()
        session.close()
    return 0


# ------------------------------------------------------------------------------ router
def cmd_router(args) -> int:
    _logging()
    if not args.listen and not args.config:
        raise InputError("router needs --listen ENDPOINT (e.g. tcp/127.0.0.1:7447)")
    session = _open(args, mode="router")
    logging.getLogger("findme.services").info("router %s listening on %s", session.zid(),
                                              ", ".join(args.listen) or args.config)
    try:
        wait_for_signal()
    finally:
        session.close()
    return 0


# ------------------------------------------------------------------------------ status
def service_statuses(session: zenoh.Session, timeout: float = 3.0, peers=None) -> list:
    """ServiceStatus of every live service instance.

    Every instance answers one status query sent to all of them (target ALL, no
    consolidation); an instance whose liveliness token is up but which does not answer (hung)
    is listed with its name alone. The tokens come from a liveliness subscriber with history
    (``peers``, a ``runtime.peers.Peers`` a long-lived caller keeps; else one made here):
    liveliness queries repeated on one long-lived session sometimes come back empty."""
    from services.runtime.peers import Peers
    own = peers is None
    peers = Peers(session, "*", seed_timeout=timeout) if own else peers
    try:
        found = {}
        for k, payload in bus.get_all(session, f"{bus.SERVICES}/*/*/status", timeout):
            try:
                st = schemas.decode(schemas.ServiceStatus, payload)
            except Exception:  # noqa: BLE001 - a foreign reply on our key: not a service
                continue
            found[(st.service, st.instance)] = st
        for name, inst in peers.all():
            found.setdefault((name, inst), schemas.ServiceStatus(service=name, instance=inst))
    finally:
        if own:
            peers.close()
    return [found[k] for k in sorted(found)]


def cmd_status(args) -> int:
    session = _open(args)
    try:
        st = service_statuses(session)
    finally:
        session.close()
    if args.json:
        import json
        from google.protobuf.json_format import MessageToDict
        print(json.dumps([MessageToDict(s, preserving_proto_field_name=True) for s in st]))
        return 0
    if not st:
        print("no Find Me services are alive on this bus")
        return 0
    now = time.time_ns()
    print(f"{'service':12s} {'instance':10s} {'up':>8s} {'in':>7s} {'out':>7s} {'errors':>7s} "
          f"{'dropped':>8s} {'queue':>6s}")
    for s in st:
        up = f"{(now - s.started_ns) / 1e9:.0f} s" if s.started_ns else "?"
        print(f"{s.service:12s} {s.instance:10s} {up:>8s} {s.frames_in:7d} {s.results_out:7d} "
              f"{s.errors:7d} {s.dropped:8d} {s.queue_depth:6d}")
        detail = delivery_detail(s)
        if detail:
            print(f"{'':23s} {detail}")
    return 0


#: status counters that say where inputs went (``runtime.inbox``), in this order
DELIVERY = ("overloaded", "expired", "superseded", "too_large", "deferred", "unreported",
            "duplicates", "recovered", "handed_over")


def delivery_detail(s) -> str:
    """One line: errors by code and where dropped/recovered inputs went (non-zero only)."""
    c = dict(s.counters)
    errs = [f"{k.removeprefix('error_').replace('_', ' ')} {v}" for k, v in sorted(c.items())
            if k.startswith("error_") and v]
    other = [f"{k.replace('_', ' ')} {c[k]}" for k in DELIVERY if c.get(k)]
    return "; ".join(x for x in (("errors: " + ", ".join(errs)) if errs else "",
                                 ", ".join(other)) if x)
