"""Joining a Zenoh bus from the command line: the bus options every command that joins one
takes (``add_bus_args``), the session they ask for (``open_bus``), the lens flags as a
capture ``Lens``, logging to stderr and a stop signal that is never lost."""

from __future__ import annotations

import dataclasses
import json
import logging
import math
import os
import sys
import threading
from pathlib import Path
from typing import NoReturn

import zenoh

from findme_core.errors import BusError, InputError
from services.pipeline.capture import Lens
from services.runtime import bus

from .options import floats


def add_bus_args(p, default_listen=(), mode: bool = True, group: bool = True):
    """The options that say how to join the bus; ``mode``: offer ``--mode`` (not for a
    router); ``group``: under their own heading in ``--help``."""
    p = p.add_argument_group("joining the bus") if group else p
    p.add_argument("--connect", action="append", default=[], metavar="ENDPOINT",
                   help="Zenoh endpoint to connect to, e.g. tcp/127.0.0.1:7447 or "
                        "tls/server.example:7447 (repeatable)")
    p.add_argument("--listen", action="append", default=list(default_listen), metavar="ENDPOINT",
                   help="Zenoh endpoint to listen on (repeatable)")
    if mode:
        p.add_argument("--mode", choices=("peer", "client"),
                       help="Zenoh mode (default: client of the router with --connect, else "
                            "peer)")
    p.add_argument("--config", metavar="FILE.json5", help="a full Zenoh configuration file")
    p.add_argument("--ca", metavar="CA.pem", help="tls/ endpoints: the CA that signed the "
                   "router's certificate (tools/make_certs.py writes certs/ca.pem)")
    p.add_argument("--user", help="user name for a router with passwords (certs/users.txt)")
    p.add_argument("--password-file", metavar="FILE",
                   help="file holding the --user's password (default: $FINDME_PASSWORD)")
    p.add_argument("--quiet", action="store_true",
                   help="log warnings and errors only (not one line per handled message)")


def bus_config(args, mode: str | None = None) -> bus.BusConfig:
    mode = mode or getattr(args, "mode", None) or ("client" if args.connect else "peer")
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


def open_bus(args, mode=None, connect_timeout_s: float | None = None) -> zenoh.Session:
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
    if connect_timeout_s is None:
        return bus.open_session(cfg)
    return _open_or_say_why(cfg, connect_timeout_s)


#: A client that fails fast tries Zenoh for this long first: opening a session takes a few
#: round trips (10 ms on loopback with TLS and a password); a router that takes part in the
#: TLS handshake at once but has given no session after this long refused it.
FIRST_TRY_S = 2.0


def _open_or_say_why(cfg: bus.BusConfig, timeout_s: float) -> zenoh.Session:
    """A client session within ``timeout_s``, or a BusError saying why not: no router
    answers (nothing listens, or the TLS handshake fails: its reason), or a router answers
    but refuses this client (a wrong user or password, or none given). Zenoh itself only
    says "timeout" and keeps retrying until then."""
    import time
    t0 = time.monotonic()
    first = min(timeout_s, FIRST_TRY_S)
    try:
        return bus.open_session(dataclasses.replace(cfg, connect_timeout_ms=int(first * 1000)))
    except BusError as e:
        if not cfg.connect or cfg.mode != "client":
            raise
        failure = e
    ca = (cfg.tls or {}).get("root_ca_certificate")
    rtts, reasons = [], []
    for ep in cfg.connect:
        rtt, why = handshake(ep, ca, max(0.5, timeout_s - (time.monotonic() - t0)))
        (rtts.append(rtt) if why is None else reasons.append(f"{ep}: {why}"))
    where = ", ".join(cfg.connect)
    if not rtts:
        raise BusError(f"no router answered at {where} ({'; '.join(reasons)})") from None
    left = timeout_s - (time.monotonic() - t0)
    if min(rtts) * 8 > first and left > 0.2:   # a slow link, not a refusal: the time left
        try:
            return bus.open_session(dataclasses.replace(cfg, connect_timeout_ms=int(left * 1000)))
        except BusError as e:
            failure = e
    if cfg.user:
        why = (f"as user {cfg.user!r} the password is wrong, or {cfg.user!r} is not one of "
               "its users (certs/users.txt on the router; --password-file or $FINDME_PASSWORD "
               "here)")
    else:
        why = "it may want a user and password (--user, --password-file)"
    raise BusError(f"the router at {where} answers but refused this client: {why}") \
        from failure


def handshake(endpoint: str, ca: str | None, timeout_s: float) -> tuple[float, str | None]:
    """(seconds, None) when something at a tcp/ or tls/ ``endpoint`` accepts a connection
    (and, for tls/, completes a TLS handshake whose certificate ``ca`` signed for the
    endpoint's host name); else (0, the reason). Other protocols: (0, None)."""
    import socket
    import ssl
    import time
    proto, _, addr = endpoint.partition("/")
    host, _, port = addr.rpartition(":")
    host = host.strip("[]")
    if proto not in ("tcp", "tls") or not port.isdigit():
        return 0.0, None
    t0 = time.monotonic()
    try:
        with socket.create_connection((host, int(port)), timeout=timeout_s) as raw:
            if proto == "tls":
                ctx = ssl.create_default_context(cafile=ca) if ca else ssl.create_default_context()
                with ctx.wrap_socket(raw, server_hostname=host):
                    pass
    except ssl.SSLCertVerificationError as e:
        return 0.0, f"its certificate is not trusted: {e.verify_message}" + (
            "" if ca else " (give the CA that signed it: --ca certs/ca.pem)")
    except (OSError, ssl.SSLError) as e:
        return 0.0, e.strerror or str(e) or type(e).__name__
    return time.monotonic() - t0, None


def lens_from_args(args) -> Lens:
    return Lens(intrinsics=floats(args.intrinsics, 4, "--intrinsics") if args.intrinsics else None,
                hfov_deg=args.hfov,
                gravity=floats(args.gravity, 3, "--gravity") if args.gravity else None,
                camera_height_m=args.camera_height,
                gravity_sigma_rad=(None if args.gravity_sigma is None
                                   else math.radians(args.gravity_sigma)))


def setup_logging(level=logging.INFO, args=None):
    """Log to stderr; ``--quiet`` on the command line raises the level to WARNING."""
    if args is not None and getattr(args, "quiet", False):
        level = max(level, logging.WARNING)
    logging.basicConfig(level=level, format="%(asctime)s %(levelname)s %(name)s: %(message)s",
                        stream=sys.stderr)


def stop_on_signal() -> threading.Event:
    """An event set by SIGTERM/SIGINT from now on: opening a session can take a while (the
    router routes before ``zenoh.open`` returns), and a stop asked meanwhile must still be a
    clean one (``wait_for_signal(event)`` then returns at once)."""
    import signal
    stop = threading.Event()
    for s in (signal.SIGTERM, signal.SIGINT):
        signal.signal(s, lambda *_: stop.set())
    return stop


def end_service_process(code: int) -> NoReturn:
    """End a service process (``findme serve``) once its service has stopped and its bus
    session is closed: flush the logs and standard streams, then ``os._exit(code)``. The
    interpreter's own exit is skipped: a native thread still in Zenoh then (a callback in
    flight, a query not yet let go) would be caught in the interpreter's finalisation and
    abort the process ("FATAL: exception not rethrown", rc -6, seen once in CI) after all
    its work was done."""
    logging.shutdown()
    for stream in (sys.stdout, sys.stderr):
        try:
            stream.flush()
        except (OSError, ValueError):
            pass  # a closed or broken stream: nothing more can be said on it
    os._exit(code)
