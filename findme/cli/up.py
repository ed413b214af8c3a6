"""``findme up``: one machine, many processes: a router and one process per service.

    findme up [--listen tcp/127.0.0.1:7447] [--hypotheses 2] [--odometry 2] [--out recordings]
              [--gateway [--http HOST:PORT] [--https | --tls-cert CERT --tls-key KEY]] [--quiet]

Starts, as child processes of this one: ``router``; ``store`` (the last minute of messages,
for a service that restarts); ``hypotheses`` x N (they share the
frames); ``selection --auto``; ``measurement``; ``odometry`` x M (they share the sessions:
a session's photos stay on one); ``mapper`` (the room's floor
plan as photos come; it plans once per drained queue, so it keeps up); ``recorder`` (sessions to
``--out``); and with ``--gateway`` the phone page's gateway (which then selects for its
pages and for nobody else, so no ``selection`` service is started: ``findme send`` selects
for itself when none runs). Each child is this same Python (``sys.executable -m
findme.cli``), so nothing depends on PATH or an activated virtual environment. Their
logs are forwarded with a ``time name |`` prefix (one line per handled message; ``--quiet``:
warnings and errors only). Ctrl-C or SIGTERM stops them all (SIGTERM, then SIGKILL after
5 s); so does the death of any one of them, and the exit status is then its status.
Once every service is on the bus it says so: ``system | ready: ...`` (a frame published
before, while the store is up, is picked up by a hypotheses instance when it starts).

Process supervision is honcho's (``honcho.manager.Manager``, the Python Foreman); the same
processes, for foreman/honcho users with the virtual environment on PATH, are in
compose/Procfile (``findme up --procfile`` prints them).
"""

from __future__ import annotations

import os
import shlex
import sys

from findme_core.errors import InputError


UP_HELP = """\
A router and one process per service on this machine, until Ctrl-C: store,
hypotheses x N, selection, measurement, odometry, mapper and the recorder
(sessions to OUT/<session>.mcap), and with --gateway the phone page. Their logs
come here, one line per handled message, prefixed with the time and the
process's name. It says "ready" once every service is on the bus, with the
command that sends photos to them; Ctrl-C (or the death of any process) stops
them all.

Examples:  findme up
           findme up --gateway --https      (the phone page too, over HTTPS)"""


def register(sub) -> None:
    p = sub.add_parser("up", help="a router and every service as processes on this machine",
                       description=UP_HELP)
    p.add_argument("--listen", default="tcp/127.0.0.1:7447", metavar="ENDPOINT",
                   help="the router's endpoint, which the services join "
                        "(default tcp/127.0.0.1:7447: this machine only)")
    p.add_argument("--hypotheses", type=int, default=2, metavar="N",
                   help="hypotheses processes sharing the frames (default 2)")
    p.add_argument("--odometry", type=int, default=2, metavar="M",
                   help="odometry processes sharing the sessions (default 2: a process "
                        "poses its photos on one core)")
    p.add_argument("--out", default="recordings", metavar="DIR",
                   help="where the recorder writes <session>.mcap (default recordings/)")
    p.add_argument("--gateway", action="store_true",
                   help="also serve the phone page (and let it select: no selection service)")
    p.add_argument("--http", default=None, metavar="HOST:PORT",
                   help="gateway: where the page is served (default 127.0.0.1:8080, "
                        "0.0.0.0:8443 with --https)")
    p.add_argument("--https", action="store_true",
                   help="gateway: HTTPS with certs/gateway.pem and certs/gateway.key "
                        "(python tools/make_certs.py certs --host THIS-MACHINE)")
    p.add_argument("--tls-cert", "--cert", dest="tls_cert", metavar="CERT.pem",
                   help="gateway: serve HTTPS with this certificate")
    p.add_argument("--tls-key", "--key", dest="tls_key", metavar="KEY.pem",
                   help="gateway: the certificate's private key")
    p.add_argument("--no-mapper", action="store_true",
                   help="no floor plans (the mapper): on a small machine under many phones it "
                        "takes CPU the poses need")
    p.add_argument("--quiet", action="store_true",
                   help="services log warnings and errors only")
    p.add_argument("--procfile", action="store_true",
                   help="print the processes as a Procfile (for foreman or honcho) and exit")
    p.set_defaults(func=cmd_up)


def processes(args) -> list[tuple[str, list[str]]]:
    """(name, findme arguments) of every process ``findme up`` starts, router first."""
    if args.hypotheses < 1:
        raise InputError(f"--hypotheses must be at least 1, got {args.hypotheses}")
    n_odo = getattr(args, "odometry", 1)
    if n_odo < 1:
        raise InputError(f"--odometry must be at least 1, got {n_odo}")
    ep = args.listen
    quiet = ["--quiet"] if args.quiet else []
    procs = [("router", ["router", "--listen", ep, *quiet]),
             ("store", ["serve", "store", "--connect", ep, *quiet])]   # recovery: see README
    procs += [(f"hypotheses{i}", ["serve", "hypotheses", "--connect", ep, "--instance", f"h{i}",
                                  *quiet]) for i in range(1, args.hypotheses + 1)]
    if not args.gateway:
        procs.append(("selection", ["serve", "selection", "--auto", "--connect", ep, *quiet]))
    procs.append(("measurement", ["serve", "measurement", "--connect", ep, *quiet]))
    procs += [(f"odometry{i}", ["serve", "odometry", "--connect", ep, "--instance", f"o{i}",
                                *quiet]) for i in range(1, n_odo + 1)]
    if not getattr(args, "no_mapper", False):
        procs.append(("mapper", ["serve", "mapper", "--connect", ep, *quiet]))
    procs.append(("recorder", ["serve", "recorder", "--connect", ep, "--out", args.out, *quiet]))
    if args.gateway:
        from .web_options import https_files
        cert, key = https_files(args)
        http = args.http or ("0.0.0.0:8443" if cert else "127.0.0.1:8080")
        tls = ["--tls-cert", cert, "--tls-key", key] if cert else []
        procs.append(("gateway", ["serve", "gateway", "--connect", ep, "--http", http, *tls, *quiet]))
    return procs


def _expected(procs) -> set[str]:
    """Liveliness tokens (``service/instance`` or ``service/*``) the started services make."""
    out = set()
    for name, argv in procs:
        if argv[0] == "serve":
            inst = argv[argv.index("--instance") + 1] if "--instance" in argv else "*"
            out.add(f"{argv[1]}/{inst}")
    return out


def _local(endpoint: str) -> str:
    """Where a process of this machine reaches a router listening on ``endpoint``."""
    proto, _, addr = endpoint.partition("/")
    host, _, port = addr.rpartition(":")
    return f"{proto}/127.0.0.1:{port}" if host in ("0.0.0.0", "[::]") else endpoint


def invoked_as(argv0: str | None = None) -> str:
    """The ``findme`` command as the user typed it, for hints: ``.venv/bin/findme`` as
    given, ``findme`` when that is what PATH finds, ``python -m findme.cli`` as that."""
    import shutil
    argv0 = sys.argv[0] if argv0 is None else argv0
    if argv0.endswith("__main__.py") or not argv0:
        return shlex.join([sys.executable, "-m", "findme.cli"])
    name = os.path.basename(argv0)
    found = shutil.which(name)
    if os.sep in argv0 and found and os.path.samefile(found, argv0):
        return name
    return shlex.quote(argv0)


def check_free(endpoint: str) -> None:
    """Refuse, before anything starts, an endpoint whose TCP port something already
    listens on (another ``findme up`` or router): the services would join that one and
    look ready while this router fails.

    Raises:
        BusError: the port is taken.
    """
    import socket

    from findme_core.errors import BusError
    proto, _, addr = endpoint.partition("/")
    host, _, port = addr.rpartition(":")
    if proto not in ("tcp", "tls") or not port.isdigit() or int(port) == 0:
        return
    host = host.strip("[]") or "0.0.0.0"
    family = socket.AF_INET6 if ":" in host else socket.AF_INET
    with socket.socket(family, socket.SOCK_STREAM) as s:
        s.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)   # TIME_WAIT is no obstacle
        try:
            s.bind((host, int(port)))
        except OSError as e:
            raise BusError(f"cannot listen on {endpoint}: {e.strerror} (another findme up or "
                           f"router? stop it, or give --listen {proto}/{host}:OTHER-PORT)") \
                from None


def announce_ready(endpoint: str, expected: set[str], say, timeout: float = 120.0,
                   command: str = "findme") -> None:
    """Wait (on liveliness, no polling) until every expected service is on the bus, then
    ``say`` the readiness line with the ``command`` that sends photos; or, after
    ``timeout``, which ones are missing."""
    import threading

    import zenoh

    from services.runtime import bus
    seen, cv = set(), threading.Condition()

    def on_token(sample):
        with cv:
            tok = "/".join(str(sample.key_expr).split("/")[-2:])
            (seen.add if sample.kind == zenoh.SampleKind.PUT else seen.discard)(tok)
            cv.notify_all()

    def missing():
        return {e for e in expected if not any(
            t == e or (e.endswith("/*") and t.startswith(e[:-1])) for t in seen)}
    try:
        session = bus.open_session(bus.BusConfig(mode="client", connect=(endpoint,)))
    except Exception as e:  # noqa: BLE001 - reported on the console, the services go on
        say(f"cannot watch for readiness: {e}\n")
        return
    try:
        sub = session.liveliness().declare_subscriber(f"{bus.SERVICES}/**", on_token, history=True)
        with cv:
            ok = cv.wait_for(lambda: not missing(), timeout)
            gone = sorted(missing())
        sub.undeclare()
    finally:
        session.close()
    if ok:
        say(f"ready: {len(expected)} services on {endpoint}; send photos with: {command} send "
            f"--connect {endpoint}\n")
    else:
        say(f"not ready after {timeout:.0f} s: no {', '.join(gone)} on the bus (see above)\n")


def cmd_up(args) -> int:
    procs = processes(args)
    if args.procfile:
        for name, argv in procs:
            print(f"{name}: {shlex.join(['findme', *argv])}")
        return 0
    import threading

    from honcho.manager import SIGNALS, Manager
    from honcho.printer import Message

    check_free(args.listen)
    gateway = [argv for name, argv in procs if name == "gateway"]
    if gateway:                                   # the page's port, as processes() chose it
        check_free("tcp/" + gateway[0][gateway[0].index("--http") + 1])
    command = invoked_as()

    class _Manager(Manager):
        def _start(self):
            super()._start()      # forks the children first: no Zenoh session in them
            threading.Thread(target=announce_ready, daemon=True, args=(
                _local(args.listen), _expected(procs), self._say),
                kwargs={"command": command}).start()

        def _say(self, text):
            self.events.put(Message(type="line", data=text, time=self._clock.now(),
                                    name="system", colour=None))

    env = {**os.environ, "PYTHONUNBUFFERED": "1"}
    sys.stdout.reconfigure(line_buffering=True)   # lines as they come, also into a pipe
    m = _Manager()
    for name, argv in procs:
        # exec: the shell honcho starts is replaced, so signals reach the service itself
        m.add_process(name, "exec " + shlex.join([sys.executable, "-m", "findme.cli", *argv]),
                      env=env)
    m.loop()
    stopped_by_us = m.returncode in {v["rc"] for v in SIGNALS.values()}
    return 0 if stopped_by_us else (m.returncode or 1)
