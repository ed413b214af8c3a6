"""The phone page's web server from the command line: its options (``add_web_args``: where
it serves, HTTPS), the certificate ``--https`` takes (``https_files``), starting the gateway
on a bus session (``start_gateway``) and ``findme serve gateway`` (``cmd_serve_gateway``).
Used by ``findme app``, ``findme serve gateway`` and ``findme up --gateway``.
"""

from __future__ import annotations

import logging
from pathlib import Path

from findme_core.errors import InputError
from services.registry import wait_for_signal

from .bus_options import end_service_process, open_bus, setup_logging

log = logging.getLogger("findme.app")


def add_web_args(p, default_http: str | None) -> None:
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


def start_gateway(session, args, instance=None):
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


def cmd_serve_gateway(args) -> int:
    setup_logging(args=args)
    session = open_bus(args)
    gw = None
    try:
        gw, url = start_gateway(session, args, instance=args.instance)
        print(f"findme serve gateway: serving {url}", flush=True)
        wait_for_signal()
    finally:
        if gw is not None:
            gw.stop()
        session.close()
    end_service_process(0)
