"""``findme app``: the phone client's web page and every processing service in one process.

    findme app [--http 127.0.0.1:8080] [--tls-cert CERT.pem --tls-key KEY.pem]

Open the printed address in a browser (a phone's, or a desktop's with a file picker).
Everything runs on one in-process Zenoh session, like ``findme run``: the gateway (page +
WebSocket bridge, services/web/gateway.py), hypotheses, measurement, and odometry, the
mapper (the room's floor plan as photos arrive) and the recorder (sessions to ``--out DIR``,
default recordings/) when those modules are installed. The gateway preselects each photo's
best hypothesis and publishes the user's choices, so no ``selection`` service runs here.
``--listen tcp/127.0.0.1:7447`` lets other processes (a recorder, ``findme status``) join.

It listens on 127.0.0.1 unless told otherwise. A phone on the network needs
``--http 0.0.0.0:8080`` and, for its camera preview and motion sensors, HTTPS
(``--tls-cert/--tls-key``): browsers allow those only on secure pages or localhost.

This module also gives ``findme serve gateway --connect ENDPOINT [--http HOST:PORT]``:
``register`` adds the web options to the ``serve`` command and runs the gateway's web
server when the service is ``gateway`` (the other services are served as before).
"""

from __future__ import annotations

import logging
import sys

from services.runtime.registry import _extra_services, add_service_args, make_handler, wait_for_signal
from services.runtime.service import Group

from . import deploy

log = logging.getLogger("findme.app")

#: Processing services embedded by ``findme app`` (those whose module is installed).
APP_SERVICES = ("hypotheses", "measurement", "odometry", "mapper")


def _web_args(p, default_http: str | None) -> None:
    p.add_argument("--http", default=default_http, metavar="HOST:PORT",
                   help="gateway: where the web page is served (default 127.0.0.1:8080; "
                        "port 0 = any free port, printed at start)")
    p.add_argument("--tls-cert", metavar="CERT.pem", help="gateway: serve HTTPS with this "
                   "certificate (phones need HTTPS for the camera preview and motion sensors)")
    p.add_argument("--tls-key", metavar="KEY.pem", help="gateway: the certificate's private key")


def register(sub) -> None:
    a = sub.add_parser("app", help="the phone web page with all services in one process",
                       description=__doc__)
    _web_args(a, "127.0.0.1:8080")
    add_service_args(a)
    a.add_argument("--no-record", action="store_true",
                   help="do not record the sessions (default: --out DIR, recordings/)")
    deploy._bus_args(a)
    a.set_defaults(func=cmd_app, out="recordings")

    serve = sub.choices.get("serve")
    if serve is not None:   # findme serve gateway --connect ENDPOINT [--http HOST:PORT]
        _web_args(serve, None)
        plain = serve.get_default("func")
        serve.set_defaults(func=lambda args: cmd_serve_gateway(args) if args.service == "gateway"
                           else plain(args))


def _start_gateway(session, args, instance=None):
    from services.web.gateway import Gateway, parse_http, ssl_context
    host, port = parse_http(args.http or "127.0.0.1:8080")
    gw = Gateway(session, host, port, ssl_context(args.tls_cert, args.tls_key), instance=instance)
    url = gw.start()
    if host not in ("127.0.0.1", "localhost", "::1"):
        log.warning("the page is reachable from other machines on %s:%d%s", host, port,
                    "" if args.tls_cert else " over plain HTTP: phones will not allow the "
                    "camera preview or motion sensors (use --tls-cert/--tls-key)")
    return gw, url


def cmd_app(args) -> int:
    deploy._logging(logging.WARNING)
    session = deploy._open(args)
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
        gw, url = _start_gateway(session, args)
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


def cmd_serve_gateway(args) -> int:
    deploy._logging()
    session = deploy._open(args)
    gw = None
    try:
        gw, url = _start_gateway(session, args, instance=args.instance)
        print(f"findme serve gateway: serving {url}", flush=True)
        wait_for_signal()
    finally:
        if gw is not None:
            gw.stop()
        session.close()
    return 0


if __name__ == "__main__":  # pragma: no cover
    from .cli import main
    sys.exit(main(["app", *sys.argv[1:]]))
