"""``findme run | serve | router | status``: the services on a Zenoh bus (what a session
prints: report.py).

* ``run``: every service in this process on one Zenoh session (the default deployment):
  photos (default: the bundled example) -> hypotheses -> selection -> scenes, motion and
  trajectory, printed as they arrive; then a measurement query.
* ``serve SERVICE``: one service in this process, joining a bus (``--connect``/``--listen``).
* ``router``: a Zenoh router for services and phones on other processes / machines.
* ``status``: which services are alive and their counters.
"""

from __future__ import annotations

import dataclasses
import json
import logging
import math
import os
import sys
import threading
import time
import uuid
from pathlib import Path

import zenoh

import schemas
from findme_core.errors import BusError, InputError
from services.runtime import bus
from services.pipeline.capture import CaptureHandler, Lens, publish_frames, sources
from services.registry import (add_service_args, make_handler, service_names,
                                      service_options, wait_for_signal)
from services.runtime.service import Group, Service

from .options import add_camera_args, finite_float, floats
from .report import Printer, _example_paths, _measure, read_photos, report_session

PIPELINE = ("hypotheses", "selection", "measurement", "odometry", "mapper")


def _bus_args(p, default_listen=()):
    p.add_argument("--connect", action="append", default=[], metavar="ENDPOINT",
                   help="Zenoh endpoint to connect to, e.g. tcp/127.0.0.1:7447 or "
                        "tls/server.example:7447 (repeatable)")
    p.add_argument("--listen", action="append", default=list(default_listen), metavar="ENDPOINT",
                   help="Zenoh endpoint to listen on (repeatable)")
    p.add_argument("--mode", choices=("peer", "client"),
                   help="Zenoh mode (default: client of the router with --connect, else peer)")
    p.add_argument("--config", metavar="FILE.json5", help="a full Zenoh configuration file")
    p.add_argument("--ca", metavar="CA.pem", help="tls/ endpoints: the CA that signed the "
                   "router's certificate (tools/make_certs.py writes certs/ca.pem)")
    p.add_argument("--user", help="user name for a router with passwords (certs/users.txt)")
    p.add_argument("--password-file", metavar="FILE",
                   help="file holding the --user's password (default: $FINDME_PASSWORD)")
    p.add_argument("--quiet", action="store_true",
                   help="log warnings and errors only (not one line per handled message)")


def register(sub) -> None:
    r = sub.add_parser("run", help="all services in one process on the example or your photos",
                       description=__doc__)
    r.add_argument("photos", nargs="*", help="image files, folders, a video or camera:N "
                                             "(default: the bundled example)")
    r.add_argument("--session", help="session id (default: a new one)")
    add_camera_args(r)
    r.add_argument("--camera-height", type=finite_float, metavar="M")
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
    s.add_argument("--camera-height", type=finite_float, metavar="M")
    s.add_argument("--wait-for", action="append", default=[], metavar="SERVICE",
                   help="capture: publish only once these services are alive")
    s.add_argument("--linger", type=float, default=120.0, metavar="S",
                   help="capture: after publishing, serve the frames until every photo's "
                        "results are in, at most S seconds (default 120), then exit")
    add_service_args(s)
    _bus_args(s)
    s.set_defaults(func=cmd_serve)

    t = sub.add_parser("router", help="a Zenoh router for services on other processes/machines")
    _bus_args(t, default_listen=())
    t.set_defaults(func=cmd_router)

    st = sub.add_parser("status", help="which services are alive, with their counters")
    _bus_args(st)
    st.add_argument("--json", action="store_true")
    st.add_argument("--wait", type=float, default=2.0, metavar="S",
                    help="how long to wait for the router (default 2 s)")
    st.set_defaults(func=cmd_status)


def bus_config(args, mode: str | None = None) -> bus.BusConfig:
    mode = mode or args.mode or ("client" if args.connect else "peer")
    if getattr(args, "config", None):
        return bus.BusConfig(mode=mode, extra={"__file__": args.config})
    tls = {"root_ca_certificate": args.ca} if getattr(args, "ca", None) else None
    user = getattr(args, "user", None)
    password = None
    if user is not None:
        pf = getattr(args, "password_file", None)
        if pf:
            try:
                password = Path(pf).read_text().strip()
            except OSError as e:
                raise InputError(f"--password-file {pf}: {e.strerror}") from None
        else:
            password = os.environ.get("FINDME_PASSWORD", "")
    return bus.BusConfig(mode=mode, listen=tuple(args.listen), connect=tuple(args.connect),
                         tls=tls, user=user, password=password)


def _open(args, mode=None, connect_timeout_s: float | None = None) -> zenoh.Session:
    """The session the command line asked for. ``connect_timeout_s``: how long a client
    waits for its router (default: the configuration's, 30 s for services, which then do
    not depend on start order); a short one makes ``status`` and ``send`` fail fast."""
    cfg = bus_config(args, mode)
    if "__file__" in cfg.extra:
        path = cfg.extra["__file__"]
        try:
            conf = zenoh.Config.from_file(path)
            if connect_timeout_s is not None:
                conf.insert_json5("connect/timeout_ms", json.dumps(
                    {"router": -1, "peer": -1, "client": int(connect_timeout_s * 1000)}))
            return zenoh.open(conf)
        except zenoh.ZError as e:
            reason = bus.zenoh_reason(e)
            if "Timeout" in reason:
                reason = f"no router answered ({reason})"
            raise BusError(f"cannot open the Zenoh session from {path}: {reason}") from None
    if connect_timeout_s is not None:
        cfg = dataclasses.replace(cfg, connect_timeout_ms=int(connect_timeout_s * 1000))
    return bus.open_session(cfg)


def _lens(args) -> Lens:
    return Lens(intrinsics=floats(args.intrinsics, 4, "--intrinsics") if args.intrinsics else None,
                hfov_deg=args.hfov,
                gravity=floats(args.gravity, 3, "--gravity") if args.gravity else None,
                camera_height_m=args.camera_height,
                gravity_sigma_rad=(None if args.gravity_sigma is None
                                   else math.radians(args.gravity_sigma)))


def _logging(level=logging.INFO, args=None):
    """Log to stderr; ``--quiet`` on the command line raises the level to WARNING."""
    if args is not None and getattr(args, "quiet", False):
        level = max(level, logging.WARNING)
    logging.basicConfig(level=level, format="%(asctime)s %(levelname)s %(name)s: %(message)s",
                        stream=sys.stderr)


# ------------------------------------------------------------------------------ run
def cmd_run(args) -> int:
    _logging(logging.WARNING)
    session_id = args.session or f"run-{uuid.uuid4().hex[:6]}"
    photos = args.photos or _example_paths()
    Path(args.out).mkdir(parents=True, exist_ok=True)
    srcs, errors = read_photos(photos)   # read and validate every photo before starting
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
        report_session(printer, capture, session_id, srcs, _lens(args), "odometry" in names, 600,
                       "mapper" in names)
        _measure(session, session_id, args, photos)
    finally:
        sub.undeclare()
        group.stop()
        session.close()
    if recorder is not None and recorder.path_of(session_id):
        print(f"recording: {recorder.path_of(session_id)}")
    return 2 if errors else 0


# ------------------------------------------------------------------------------ serve
def alive_services(session: zenoh.Session, timeout: float = 3.0) -> set[str]:
    """Names of the services whose liveliness tokens are on the bus now."""
    return {str(r.ok.key_expr).split("/")[-2] for r in
            session.liveliness().get(f"{bus.SERVICES}/**", timeout=timeout) if r.ok}


def cmd_serve(args) -> int:
    _logging(args=args)
    if args.service == "capture" and (not args.photos or not args.session):
        raise InputError("capture needs --session and at least one photo")
    stop = stop_on_signal()
    session = _open(args)
    handler = make_handler(args.service, args)
    if handler.nice and hasattr(os, "nice"):
        os.nice(handler.nice)
    svc = Service(handler, session, instance=args.instance, **service_options(args)).start()
    try:
        if args.service == "capture":
            return _serve_capture(args, session, svc)
        wait_for_signal(stop)
    finally:
        svc.stop()
        session.close()
    return 0


def _serve_capture(args, session, svc) -> int:
    """Publish the photos, then stay (serving the frames to services that ask for them)
    until each photo's results are in, or ``--linger`` seconds; bad files are reported (log
    and an Error on the session) and the rest is sent. Exit status 2 if any was bad."""
    import signal
    signal.signal(signal.SIGTERM, signal.SIG_DFL)          # a one-shot command: stop now
    signal.signal(signal.SIGINT, signal.default_int_handler)
    log = logging.getLogger("findme.services")
    for name in args.wait_for:
        bus.wait_alive(session, name)
    printer = Printer(args.session, out=open(os.devnull, "w"))   # noqa: SIM115 - closed below
    sub = session.declare_subscriber(f"findme/{args.session}/**", printer)
    errors: list = []
    try:
        n = publish_frames(svc, args.session, sources(args.photos, errors=errors), _lens(args))
        for path, e in errors:
            svc.report(bus.key(args.session, "frame"), e)
        log.info("capture: published %d frames of %s (%d refused)", n, args.session, len(errors))
        odometry = "odometry" in alive_services(session)
        deadline = time.monotonic() + args.linger
        for i in range(n):
            if not printer.wait(printer.photo_done(i, odometry), max(0.0, deadline - time.monotonic())):
                log.warning("capture: photo %d of %s has no result after %.0f s; stopping",
                            i, args.session, args.linger)
                break
        else:
            log.info("capture: every photo of %s has its results; stopping", args.session)
    finally:
        sub.undeclare()
        printer.out.close()
    return 2 if errors else 0


# ------------------------------------------------------------------------------ router
def stop_on_signal() -> threading.Event:
    """An event set by SIGTERM/SIGINT from now on: opening a session can take a while (the
    router routes before ``zenoh.open`` returns), and a stop asked meanwhile must still be a
    clean one (``wait_for_signal(event)`` then returns at once)."""
    import signal
    stop = threading.Event()
    for s in (signal.SIGTERM, signal.SIGINT):
        signal.signal(s, lambda *_: stop.set())
    return stop


def cmd_router(args) -> int:
    _logging(args=args)
    if not args.listen and not args.config:
        raise InputError("router needs --listen ENDPOINT (e.g. tcp/127.0.0.1:7447)")
    stop = stop_on_signal()
    session = _open(args, mode="router")
    logging.getLogger("findme.services").info("router %s listening on %s", session.zid(),
                                              ", ".join(args.listen) or args.config)
    try:
        wait_for_signal(stop)
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
    session = _open(args, connect_timeout_s=args.wait)
    try:
        st = service_statuses(session)
    finally:
        session.close()
    if args.json:
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
