"""``findme send``: photos from this machine to services running elsewhere, with their results.

    findme send [PHOTOS...] --connect ENDPOINT [--session S] [--ca CA.pem --user U]
                [--measure U,V[,floor|wall] ...] [--config FILE.json5]

The client side of the many-process and phone + server deployments (compose/README.md):
it joins the bus as a client of the router, checks that the services the report needs are
alive (hypotheses, measurement, and odometry for two photos or more), publishes the photos
(default: the bundled example pair) as frames of a new session and prints what
``findme run`` prints: each photo's hypotheses, selection and scene, the motion and the
poses, then a measurement. Like a phone page, it selects each photo's best hypothesis itself
when no ``selection`` service runs (the phone + server deployment has none: its clients
choose). Errors the services publish about the session are printed one line each.

Exit status: 0 when every photo got its results; 2 when the router or a needed service is
not there (one line, within a few seconds), a photo could not be read (the others are sent)
or the results did not all arrive within ``--timeout``.
"""

from __future__ import annotations

import logging
import uuid

import schemas
from findme_core.errors import BusError, HypothesisError, InputError
from services.pipeline.capture import CaptureHandler
from services.runtime import bus
from services.runtime.handler import Input, Output
from services.runtime.service import Service

from .. import report
from .bus_options import add_bus_args, lens_from_args, open_bus, setup_logging
from .options import said_points
from .status import alive_services
from .options import add_camera_args


class ClientHandler(CaptureHandler):
    """What one client needs on the bus for its own session: its frames (and selections)
    cached for services that ask, and, with ``select``, rank 1 of each photo chosen as soon
    as its hypotheses arrive (by AUTO, as the phone page's gateway does)."""

    name = "capture"

    def __init__(self, session: str, select: bool):
        self.cache_keys = (f"findme/{session}/frame/*", f"findme/{session}/selection/*")
        self.inputs = ((Input(f"findme/{session}/hypotheses/*", schemas.HypothesisSet),)
                       if select else ())

    def on_message(self, key, hset):
        if not hset.hypotheses:
            raise HypothesisError(f"photo {hset.index} has no hypothesis to select: {hset.reason}")
        k = bus.parse_key(key)
        sel = schemas.Selection(session=k.session, index=hset.index, rank=1,
                                by=schemas.SELECTED_BY_AUTO)
        return [Output(bus.key(k.session, "selection", hset.index), sel)]


SEND_HELP = """\
Photos from this machine to services running elsewhere (findme up, or a server),
as a new session, with what findme run prints: each photo's hypotheses, the one
selected, its scene and where it was taken, the motion between photos, the
floor plan, then a measurement. Without photos it sends the bundled example
pair. It first checks that the router answers and the services it needs are
alive, and says in one line what is missing (exit status 2) within --wait
seconds; so too when the router refuses this client (a wrong password, or a
session its access control does not allow this user). When no selection service
runs it picks each photo's best hypothesis itself, as the phone page does.

Examples:  findme send --connect tcp/127.0.0.1:7447
           FINDME_PASSWORD=... findme send photos/ --connect tls/SERVER:7447 \\
               --ca certs/ca.pem --user alice"""


#: How long the router may take to pass photo 0 back to this machine before the session
#: counts as refused (a round trip: milliseconds on a LAN).
PASS_ON_S = 2.0


class RouterEcho:
    """Whether the router passes this session's photos on (its access control may refuse
    a session silently): a second client session, with the same credentials, subscribes to
    the session's frames and must see photo 0 come back through the router. A query through
    the router after the subscription makes sure the router has taken it in (a link's
    messages are handled in order) before photo 0 is sent."""

    def __init__(self, args, session_id: str):
        import threading
        self.cv, self.seen = threading.Condition(), False
        self.session = open_bus(args, mode="client", connect_timeout_s=args.wait)
        self.sub = self.session.declare_subscriber(bus.key(session_id, "frame", "*"), self._cb)
        for _ in self.session.liveliness().get(f"{bus.SERVICES}/**", timeout=args.wait):
            pass

    def _cb(self, sample) -> None:
        with self.cv:
            self.seen = True
            self.cv.notify_all()

    def wait(self, timeout: float) -> bool:
        with self.cv:
            return self.cv.wait_for(lambda: self.seen, timeout)

    def close(self) -> None:
        self.sub.undeclare()
        self.session.close()


def _refused(args, session_id: str) -> str:
    """Why the router did not pass photo 0 on, for the user."""
    where = ", ".join(args.connect) or args.config
    who = f"user {args.user!r}" if args.user else "this client"
    hint = (f" (a device may only use sessions that start with its user name, "
            f"{args.user}-...; leave --session out for a new one)"
            if args.user and not session_id.startswith(f"{args.user}-") else "")
    return (f"the router at {where} did not pass on photo 0 of session {session_id!r} within "
            f"{PASS_ON_S:g} s: its access control does not let {who} use that session{hint}")


def register(sub) -> None:
    p = sub.add_parser("send", help="photos to running services, with their results",
                       description=SEND_HELP)
    p.add_argument("photos", nargs="*", metavar="PHOTO",
                   help="image files, folders or a video (default: the bundled example pair)")
    p.add_argument("--session", help="session id (default: a new one, starting with --user "
                                     "when given, as a router with per-device keys requires)")
    add_camera_args(p)
    p.add_argument("--camera-height", type=float, metavar="M",
                   help="camera height above the floor in metres (default: PHOTO.json's, "
                        "else unknown: lengths in camera heights)")
    p.add_argument("--measure", action="append", metavar="U,V[,floor|wall|top]",
                   help="a pixel of photo 0 to measure at the end (repeatable); with floor, "
                        "wall or top: the surface you say it is on (top: the top of something "
                        "standing on the floor line below it, with its height)")
    p.add_argument("--timeout", type=float, default=120.0, metavar="S",
                   help="seconds to wait for each photo's results (default 120)")
    p.add_argument("--wait", type=float, default=5.0, metavar="S",
                   help="seconds to wait for the router and the services (default 5)")
    add_bus_args(p, mode=False)
    p.set_defaults(func=cmd_send)


def cmd_send(args) -> int:
    setup_logging(logging.WARNING)
    if not args.connect and not args.config:
        raise InputError("send needs --connect ENDPOINT (e.g. tcp/127.0.0.1:7447) or --config")
    photos = args.photos or report.example_paths()
    srcs, errors = report.read_photos(photos)
    pixels, said = said_points(args.measure or [], "--measure")
    prefix = f"{args.user}-" if args.user else "send-"
    session_id = args.session or f"{prefix}{uuid.uuid4().hex[:8]}"
    bus.key(session_id, "frame")                      # a valid session id, or say why now
    session = open_bus(args, mode="client", connect_timeout_s=args.wait)
    svc = sub = echo = None
    try:
        needed = ["hypotheses", "measurement"] + (["odometry"] if len(srcs) > 1 else [])
        for name in needed:
            try:
                bus.wait_alive(session, name, args.wait)
            except BusError:
                where = ", ".join(args.connect) or args.config
                raise BusError(f"no {name} service is running on the bus at {where} (start "
                               f"the services: findme up, or findme serve {name} --connect "
                               "...)") from None
        select = "selection" not in alive_services(session, args.wait)
        printer = report.Printer(session_id)
        sub = session.declare_subscriber(f"findme/{session_id}/**", printer)
        svc = Service(ClientHandler(session_id, select), session).start()
        echo = RouterEcho(args, session_id)

        def passed_on():
            if not echo.wait(PASS_ON_S):
                raise BusError(_refused(args, session_id))
        report.report_session(printer, svc, session_id, srcs, lens_from_args(args),
                              "odometry" in needed, args.timeout, on_first=passed_on)
        report.measure(session, session_id, pixels, example=not args.photos, said=said,
                       scene=printer.seen.get(f"findme/{session_id}/scene/0"))
    finally:
        if echo is not None:
            echo.close()
        if sub is not None:
            sub.undeclare()
        if svc is not None:
            svc.stop()
        session.close()
    return 2 if errors else 0
