"""``findme serve | router``: one service, or a Zenoh router, in this process.

* ``serve SERVICE``: one service in this process, joining a bus (``--connect``/``--listen``);
  ``serve gateway`` also runs the phone page's web server (``web_options``).
* ``router``: a Zenoh router for services and phones on other processes / machines.
"""

from __future__ import annotations

import logging
import os
import time

from findme_core.errors import InputError
from services.pipeline.capture import publish_frames, sources
from services.runtime import bus
from services.registry import (add_service_args, make_handler, service_names,
                                      service_options, wait_for_signal)
from services.runtime.service import Service

from ..report import Printer
from .bus_options import (add_bus_args, end_service_process, lens_from_args, open_bus,
                          setup_logging, stop_on_signal)
from .options import add_camera_args, finite_float
from .status import alive_services
from .web_options import add_web_args, cmd_serve_gateway


SERVE_HELP = """\
One service in this process, joining a bus (a router: --connect ENDPOINT): the
way to spread the services over processes and machines (findme up starts them
all on one machine). The services:

  capture      sends photos (PHOTO... --session S), waits for their results
  hypotheses   each photo's floor-wall boundary hypotheses
  selection    picks a hypothesis of each photo (rank 1, or --interactive)
  measurement  the 3D scene of each selected hypothesis, and measurements
  odometry     the motion between photos and where each was taken
  mapper       the room's floor plan as photos come
  store        the last minute of messages, for services that restart
  recorder     every session to OUT/<session>.mcap
  viewer       every session in Rerun
  gateway      the phone page (--http, --https) and its bridge to the bus

Example:  findme serve hypotheses --connect tcp/127.0.0.1:7447"""

ROUTER_HELP = """\
A Zenoh router: the meeting point of services and clients in other processes or
on other machines (findme up starts one). Give where it listens (--listen), or a
whole Zenoh configuration (--config, e.g. TLS with passwords and per-device
access control: compose/README.md).

Example:  findme router --listen tcp/0.0.0.0:7447"""


def register(sub) -> None:
    s = sub.add_parser("serve", help="one service in this process, joining a bus",
                       description=SERVE_HELP)
    s.add_argument("service", choices=service_names(), metavar="SERVICE",
                   help="which service (see above)")
    s.add_argument("photos", nargs="*", metavar="PHOTO",
                   help="capture: image files, folders, a video or camera:N")
    s.add_argument("--session", help="capture: session id")
    s.add_argument("--instance", help="instance id (default: random)")
    add_camera_args(s)
    s.add_argument("--camera-height", type=finite_float, metavar="M",
                   help="capture: camera height above the floor in metres (default: "
                        "PHOTO.json's, else unknown: lengths in camera heights)")
    s.add_argument("--wait-for", action="append", default=[], metavar="SERVICE",
                   help="capture: publish only once these services are alive")
    s.add_argument("--linger", type=float, default=120.0, metavar="S",
                   help="capture: after publishing, serve the frames until every photo's "
                        "results are in, at most S seconds (default 120), then exit")
    add_service_args(s)
    add_web_args(s, None)   # findme serve gateway --connect ENDPOINT [--http HOST:PORT]
    add_bus_args(s)
    s.set_defaults(func=lambda args: cmd_serve_gateway(args) if args.service == "gateway"
                   else cmd_serve(args))

    t = sub.add_parser("router", help="a Zenoh router for services on other processes/machines",
                       description=ROUTER_HELP)
    add_bus_args(t, default_listen=(), mode=False)
    t.set_defaults(func=cmd_router)


def cmd_serve(args) -> int:
    setup_logging(args=args)
    if args.service == "capture" and (not args.photos or not args.session):
        raise InputError("capture needs --session and at least one photo")
    stop = stop_on_signal()
    handler = make_handler(args.service, args)
    if handler.background:   # before the bus: its threads inherit the policy
        background_scheduling()
    session = open_bus(args)
    # after the bus (Linux keeps a niceness per thread): this thread and the service's,
    # which do the work, yield the CPU; Zenoh's I/O threads keep their priority, so that a
    # niced subscriber still takes its messages off the link promptly (the router does
    # not wait on it) and its intake counts and refuses at once
    if handler.nice and hasattr(os, "nice"):
        os.nice(handler.nice)
    svc = Service(handler, session, instance=args.instance, **service_options(args)).start()
    code = 0
    try:
        if args.service == "capture":
            code = _serve_capture(args, session, svc)
        else:
            wait_for_signal(stop)
    finally:
        svc.stop()
        session.close()
    end_service_process(code)


def background_scheduling() -> bool:
    """Put this process's threads, and those it starts from now on, under Linux's
    SCHED_BATCH policy (``Handler.background``); False where the OS has no such policy or
    refuses it (said in the log: the service runs as it is)."""
    if not hasattr(os, "SCHED_BATCH"):
        return False
    try:
        os.sched_setscheduler(0, os.SCHED_BATCH, os.sched_param(0))
    except OSError as e:
        logging.getLogger("findme.services").warning(
            "cannot run as background work (SCHED_BATCH: %s); running as is", e.strerror)
        return False
    return True


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
        n = publish_frames(svc, args.session, sources(args.photos, errors=errors), lens_from_args(args))
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


def cmd_router(args) -> int:
    setup_logging(args=args)
    if not args.listen and not args.config:
        raise InputError("router needs --listen ENDPOINT (e.g. tcp/127.0.0.1:7447)")
    stop = stop_on_signal()
    session = open_bus(args, mode="router")
    logging.getLogger("findme.services").info("router %s listening on %s", session.zid(),
                                              ", ".join(args.listen) or args.config)
    try:
        wait_for_signal(stop)
    finally:
        session.close()
    return 0
