"""``findme app``: the phone client's web page and every processing service in one process.

    findme app [--http 127.0.0.1:8080] [--https | --tls-cert CERT.pem --tls-key KEY.pem]

Open the printed address in a browser (a phone's, or a desktop's with a file picker).
Everything runs on one in-process Zenoh session, like ``findme run``: the gateway (page +
WebSocket bridge, services/web/gateway.py), hypotheses, measurement, and odometry, the
mapper (the room's floor plan as photos arrive) and the recorder (sessions to ``--out DIR``,
default recordings/) when those modules are installed. The gateway preselects each photo's
best hypothesis and publishes the user's choices, so no ``selection`` service runs here.
``--listen tcp/127.0.0.1:7447`` lets other processes (a recorder, ``findme status``) join.

It listens on 127.0.0.1 unless told otherwise. A phone on the network needs HTTPS for its
camera preview and motion sensors (browsers allow those only on secure pages or
localhost): ``--https`` serves https://0.0.0.0:8443/ with certs/gateway.pem (made by
tools/make_certs.py; the phone trusts it once certs/ca.crt is installed, README), or give
``--tls-cert/--tls-key`` (alias ``--cert/--key``) and ``--http HOST:PORT``.
"""

from __future__ import annotations

import logging

from services.registry import _extra_services, add_service_args, make_handler, wait_for_signal
from services.runtime.service import Group

from .bus_options import add_bus_args, open_bus, setup_logging
from .web_options import add_web_args, start_gateway

log = logging.getLogger("findme.app")

#: Processing services embedded by ``findme app`` (those whose module is installed).
APP_SERVICES = ("hypotheses", "measurement", "odometry", "mapper")


APP_HELP = """\
The phone page and every processing service in this one process: open the
printed address in a browser (a phone's, or a desktop's with a file picker),
take or pick photos, choose a boundary, tap points to measure, see where you
moved and the room's floor plan as it grows. Sessions are recorded to
OUT/<session>.mcap (default recordings/).

It serves http://127.0.0.1:8080/ (this machine only). A phone needs HTTPS with a
certificate it trusts for the live camera and the motion sensors: make one with
python tools/make_certs.py certs --host THIS-MACHINE'S-ADDRESS, then --https
serves https://0.0.0.0:8443/ (compose/README.md: "The phone trusts the page").

Examples:  findme app
           findme app --https"""


def register(sub) -> None:
    a = sub.add_parser("app", help="the phone page with every service, in this process",
                       description=APP_HELP)
    add_web_args(a, None)
    add_service_args(a, selection=False, out_help="where sessions are recorded (default "
                     "recordings)")
    a.add_argument("--no-record", action="store_true",
                   help="do not record the sessions (default: --out DIR, recordings/)")
    add_bus_args(a)
    a.set_defaults(func=cmd_app, out="recordings")


def cmd_app(args) -> int:
    setup_logging(logging.WARNING)
    session = open_bus(args)
    group = Group(session)
    gw = None
    try:
        names = []
        if not args.no_record and "recorder" in _extra_services():
            # first in, so stopped last: it records everything (as findme run)
            names.append(group.add(make_handler("recorder", args)).handler.name)
        for name in APP_SERVICES:
            try:
                names.append(group.add(make_handler(name, args)).handler.name)
            except ImportError:   # a service whose module is not installed (yet)
                log.info("%s: not installed, not started", name)
        gw, url = start_gateway(session, args)
        where = ", ".join(args.listen) or "in-process"
        # the readiness line (tests and scripts wait for it)
        print(f"findme app: serving {url} (bus: {where}; services: {', '.join(names + ['gateway'])})",
              flush=True)
        wait_for_signal()
    finally:
        if gw is not None:
            gw.stop()
        group.stop()
        session.close()
    return 0
