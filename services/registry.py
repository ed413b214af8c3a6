"""Service names -> handlers, the command-line options each takes, and the shared main loop
(SIGTERM/SIGINT stop it) used by ``findme serve`` and ``findme run``."""

from __future__ import annotations

import logging
import signal
import threading

from findme_core.errors import InputError

from .runtime.handler import Handler

log = logging.getLogger("findme.services")


def add_service_args(p, selection: bool = True, out_help: str | None = None) -> None:
    """Options of every service (unused ones are ignored by the others); without
    ``selection`` no ``--auto``/``--interactive`` (a command that runs no selection service);
    ``out_help``: what ``--out`` is for in that command."""
    p.add_argument("--method", default="findme", choices=("findme", "paper"),
                   help="hypotheses: findme (default) or paper (the paper's method)")
    p.add_argument("--max", type=int, default=10, metavar="N",
                   help="hypotheses: at most N per photo (default 10)")
    p.add_argument("--latest", type=int, metavar="N",
                   help="hypotheses: keep only the newest N frames (live video); every skipped "
                        "frame is counted as dropped. Default: never drop a frame")
    if selection:
        sel = p.add_mutually_exclusive_group()
        sel.add_argument("--auto", action="store_true", help="selection: take rank 1 (default)")
        sel.add_argument("--interactive", action="store_true",
                         help="selection: write the numbered image and ask which hypothesis "
                              "in the terminal")
    p.add_argument("--out", default=".", metavar="DIR",
                   help=out_help or "where selection images (and recordings) are written")
    d = p.add_argument_group("delivery (every service)")
    d.add_argument("--queue-depth", type=int, metavar="N",
                   help="messages a session may have waiting; more are answered OVERLOADED "
                        "(default 32; recorder 4096)")
    d.add_argument("--max-wait", type=float, default=10.0, metavar="S",
                   help="a message that waited longer in the queue is answered OVERLOADED "
                        "instead of handled (default 10; the recorder and the store keep all)")
    d.add_argument("--sweep", type=float, default=10.0, metavar="S",
                   help="seconds between recovery sweeps: unanswered inputs the bus still holds "
                        "are fetched and handled (default 10; also at start and when an "
                        "instance comes or goes)")
    d.add_argument("--idle", type=float, default=600.0, metavar="S",
                   help="forget a session idle this long: measurement and odometry state, the "
                        "recorder's open file, cached results (default 600; rebuilt from the "
                        "bus when it comes back)")
    d.add_argument("--gap-wait", type=float, default=5.0, metavar="S",
                   help="odometry: wait this long for a lower photo's selection before "
                        "chaining past it (default 5)")
    d.add_argument("--window", type=float, default=60.0, metavar="S",
                   help="store: hold every message this long for services that missed it "
                        "(default 60)")
    d.add_argument("--latch", type=float, default=900.0, metavar="S",
                   help="store: hold the latest small result of each key this long (default 900)")


def service_options(args) -> dict:
    """Service keyword arguments from the delivery options."""
    depth = getattr(args, "queue_depth", None)
    if depth is not None and depth < 1:
        raise InputError(f"--queue-depth must be at least 1, got {depth}")
    wait = getattr(args, "max_wait", 10.0)
    return {"fifo_depth": depth, "sweep_s": getattr(args, "sweep", 10.0),
            "max_wait_s": wait if wait and wait > 0 else None,
            "cache_age_s": getattr(args, "idle", 600.0)}


def make_handler(name: str, args) -> Handler:
    """The handler of service ``name`` configured from parsed ``args``."""
    if name == "hypotheses":
        from .pipeline.hypotheses import HypothesesHandler
        if args.latest is not None and args.latest < 1:
            raise InputError(f"--latest must be at least 1, got {args.latest}")
        return HypothesesHandler(args.method, args.max,
                                 "latest" if args.latest else "all", args.latest or 64)
    if name == "selection":
        from .pipeline.selection import SelectionHandler, TerminalChooser
        interactive = getattr(args, "interactive", False)
        return SelectionHandler(TerminalChooser(args.out) if interactive else None)
    if name == "measurement":
        from .pipeline.measurement import MeasurementHandler
        return MeasurementHandler(idle_s=getattr(args, "idle", 600.0))
    if name == "odometry":
        from .pipeline.odometry import OdometryHandler
        return OdometryHandler(gap_wait_s=getattr(args, "gap_wait", 5.0),
                               idle_s=getattr(args, "idle", 600.0))
    if name == "mapper":
        from .pipeline.mapper import make_mapper
        return make_mapper(args)
    if name == "store":
        from .runtime.store import make_store
        return make_store(args)
    if name == "capture":
        from .pipeline.capture import CaptureHandler
        return CaptureHandler()
    extra = _extra_services()
    if name in extra:
        return extra[name](args)
    raise InputError(f"unknown service {name!r}; choose one of {', '.join(service_names())}")


def _extra_services() -> dict:
    """Services defined in other modules (recorder, viewer, gateway), if present."""
    out = {}
    try:
        from .recording.recorder import make_recorder
        out["recorder"] = make_recorder
    except ImportError:
        pass
    try:
        from .recording.viewer import make_viewer
        out["viewer"] = make_viewer
    except ImportError:
        pass
    try:
        from .web.gateway import make_gateway
        out["gateway"] = make_gateway
    except ImportError:  # aiohttp not installed
        pass
    return out


def service_names() -> list[str]:
    return ["capture", "hypotheses", "selection", "measurement", "odometry", "mapper", "store",
            *_extra_services()]


def wait_for_signal(stop: threading.Event | None = None) -> None:
    """Block until SIGTERM or SIGINT (or ``stop`` is set)."""
    stop = stop or threading.Event()

    def handler(signum, frame):
        log.info("signal %s: stopping", signal.Signals(signum).name)
        stop.set()

    old = {s: signal.signal(s, handler) for s in (signal.SIGTERM, signal.SIGINT)}
    try:
        while not stop.wait(0.5):
            pass
    finally:
        for s, h in old.items():
            signal.signal(s, h)
