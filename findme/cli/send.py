"""``findme send``: photos from this machine to services running elsewhere, with their results.

    findme send [PHOTOS...] --connect ENDPOINT [--session S] [--ca CA.pem --user U]
                [--measure U,V ...] [--config FILE.json5]

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
from .options import floats
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


def register(sub) -> None:
    p = sub.add_parser("send", help="send photos to running services and print their results",
                       description=__doc__,
                       formatter_class=__import__("argparse").RawDescriptionHelpFormatter)
    p.add_argument("photos", nargs="*", help="image files, folders or a video "
                                             "(default: the bundled example pair)")
    p.add_argument("--session", help="session id (default: a new one, starting with --user "
                                     "when given, as a router with per-device keys requires)")
    add_camera_args(p)
    p.add_argument("--camera-height", type=float, metavar="M")
    p.add_argument("--measure", action="append", metavar="U,V",
                   help="pixels of photo 0 to measure at the end (repeatable)")
    p.add_argument("--timeout", type=float, default=120.0, metavar="S",
                   help="seconds to wait for each photo's results (default 120)")
    p.add_argument("--wait", type=float, default=5.0, metavar="S",
                   help="seconds to wait for the router and the services (default 5)")
    add_bus_args(p)
    p.set_defaults(func=cmd_send)


def cmd_send(args) -> int:
    setup_logging(logging.WARNING)
    if not args.connect and not args.config:
        raise InputError("send needs --connect ENDPOINT (e.g. tcp/127.0.0.1:7447) or --config")
    photos = args.photos or report.example_paths()
    srcs, errors = report.read_photos(photos)
    prefix = f"{args.user}-" if args.user else "send-"
    session_id = args.session or f"{prefix}{uuid.uuid4().hex[:8]}"
    bus.key(session_id, "frame")                      # a valid session id, or say why now
    session = open_bus(args, mode="client", connect_timeout_s=args.wait)
    svc = sub = None
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
        report.report_session(printer, svc, session_id, srcs, lens_from_args(args),
                              "odometry" in needed, args.timeout)
        pixels = [floats(p, 2, "--measure") for p in args.measure or []]
        report.measure(session, session_id, pixels, example=not args.photos)
    finally:
        if sub is not None:
            sub.undeclare()
        if svc is not None:
            svc.stop()
        session.close()
    return 2 if errors else 0
