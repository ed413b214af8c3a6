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

This module also gives ``findme serve gateway --connect ENDPOINT [--http HOST:PORT]``:
``register`` adds the web options to the ``serve`` command and runs the gateway's web
server when the service is ``gateway`` (the other services are served as before).
"""

from __future__ import annotations

import logging
import sys
from pathlib import Path

from findme_core.errors import InputError

from services.registry import _extra_services, add_service_args, make_handler, wait_for_signal
from services.runtime.service import Group

from . import deploy

log = logging.getLogger("findme.app")

#: Processing services embedded by ``findme app`` (those whose module is installed).
APP_SERVICES = ("hypotheses", "measurement", "odometry", "mapper")


def _web_args(p, default_http: str | None) -> None:
    p.add_argument("--http", default=default_http, metavar="HOST:PORT",
                   help="gateway: where the web page is served (default 127.0.0.1:8080, or "
                        "0.0.0.0:8443 with --https; port 0 = any free port, printed at start)")
    p.add_argument("--https", action="store_true",
                   help="gateway: serve HTTPS with certs/gateway.pem and certs/gateway.key "
                        "(python tools/make_certs.py certs --host THIS-MACHINE); phones give "
                        "the camera preview and motion sensors only to secure pages")
    p.add_argument("--tls-cert", "--cert", dest="tls_cert", metavar="CERT.pem",
                   help="gateway: serve HTTPS with this certificate")
    p.add_argument("--tls-key", "--key", dest="tls_key", metavar="KEY.pem",
                   help="gateway: the certificate's private key")
    p.add_argument("--allow-origin", action="append", default=[], metavar="URL",
                   help="gateway: a web origin allowed to open the page's WebSocket, e.g. "
                        "https://findme.example.org behind a proxy (repeatable; pages loaded "
                        "from this server by IP address, localhost or this machine's name are "
                        "always allowed)")
    p.add_argument("--trusted-proxy", action="append", default=[], metavar="IP",
                   help="gateway: a reverse proxy whose X-Forwarded-For names the client "
                        "(per-client page limits count clients, not the proxy; repeatable)")


#: Where ``--https`` finds the gateway's certificate (tools/make_certs.py writes them).
HTTPS_FILES = ("certs/gateway.pem", "certs/gateway.key")


def https_files(args) -> tuple[str | None, str | None]:
    """(certificate, key) the gateway serves HTTPS with, or (None, None) for plain HTTP.

    Raises:
        InputError: only one of --tls-cert/--tls-key, or --https without the files.
    """
    cert, key = args.tls_cert, args.tls_key
    if bool(cert) != bool(key):
        raise InputError("--tls-cert and --tls-key go together (a certificate and its key)")
    if not cert and getattr(args, "https", False):
        cert, key = HTTPS_FILES
        missing = [f for f in HTTPS_FILES if not Path(f).is_file()]
        if missing:
            raise InputError(f"--https needs {' and '.join(missing)} (in {Path.cwd()}): make "
                             "them with python tools/make_certs.py certs --host "
                             "THIS-MACHINE'S-NAME-OR-IP, or give --tls-cert/--tls-key")
    return cert, key


def lan_address() -> str | None:
    """This machine's address on its default route (no packet is sent), or None."""
    import socket
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        try:
            s.connect(("192.0.2.1", 9))   # TEST-NET-1: only picks the outgoing interface
            return s.getsockname()[0]
        except OSError:
            return None


def register(sub) -> None:
    a = sub.add_parser("app", help="the phone web page with all services in one process",
                       description=__doc__)
    _web_args(a, None)
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
    from services.web.page_guard import served_names
    cert, key = https_files(args)
    host, port = parse_http(args.http or ("0.0.0.0:8443" if cert else "127.0.0.1:8080"))
    gw = Gateway(session, host, port, ssl_context(cert, key), instance=instance,
                 allowed_origins=args.allow_origin, own_names=served_names(cert),
                 trusted_proxies=args.trusted_proxy)
    url = gw.start()
    if host not in ("127.0.0.1", "localhost", "::1"):
        if not cert:
            log.warning("the page is reachable from other machines on %s:%d over plain HTTP: "
                        "phones will not allow the camera preview or motion sensors (use "
                        "--https or --tls-cert/--tls-key)", host, port)
        else:
            lan = lan_address() if host in ("0.0.0.0", "::") else host
            log.warning("the page is reachable from other machines: %s", url.replace(
                f"//{host}:", f"//{lan}:") if lan else url)
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
    deploy._logging(args=args)
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
