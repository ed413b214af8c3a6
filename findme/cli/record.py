"""``findme recover | view | replay | regress``: working with recorded sessions (MCAP).

* ``recover BROKEN.mcap -o FIXED.mcap``: salvage a recording whose recorder died.
* ``view SESSION.mcap``: the session in Rerun (a viewer, or ``SESSION.rrd`` beside it);
  ``view --live``: every session on the bus as it happens.
* ``replay SESSION.mcap``: put a recording back on the bus so the services run on it again.
* ``regress SESSION.mcap``: run its frames (and its selections) through the current
  services and compare every result with the recorded one; exit 1 on a difference.
"""

from __future__ import annotations

import argparse
import math
from pathlib import Path

import schemas
from findme_core.errors import InputError, RecordingError
from services.runtime import bus
from services.recording.mcap_reader import Recorded, read_available
from services.recording.mcap_recover import recover

from ..regression.diff import COMPARES, TOLERANCES
from ..regression.regress import regress
from ..regression.replay import rename_session, replay
from .bus_options import add_bus_args, open_bus, setup_logging


RECOVER_HELP = """\
Salvage a recording whose recorder was killed (it has no end): every whole part
of it is copied into a new, finished file, and what was kept or dropped is said.

Example:  findme recover recordings/s.mcap -o s-fixed.mcap"""

VIEW_HELP = """\
A recorded session in Rerun: the photos with their hypotheses, scenes and
points, the camera path and the floor plan. With a display it opens a viewer;
without one it writes SESSION.rrd beside the recording (open it with rerun). A
recording still being written is shown as far as it is complete. --live shows
every session on a bus as it happens.

Examples:  findme view recordings/s.mcap
           findme view --live --connect tcp/127.0.0.1:7447 --web"""

REPLAY_HELP = """\
Put a recorded session back on the bus so that the running services work on it
again: its photos, and the user's choices and measurements (a choice waits for
its photo's hypotheses, a measurement is asked again once its scene is there),
paced as recorded (--rate) or as fast as the bus takes them (--max). A
recording still being written is replayed as far as it is complete.

Example:  findme replay recordings/s.mcap --connect tcp/127.0.0.1:7447 --max"""

REGRESS_HELP = """\
Run a recorded session's photos and choices through the current services (in
this process) and compare every result with the recorded one, within stated
tolerances; exit status 1 on a difference, listing each. The golden recordings
in recordings/golden/ are the regression suite. A recording that is not finished
is refused with the reason.

Example:  findme regress recordings/golden/examples-pair.mcap"""


def register(sub) -> None:
    r = sub.add_parser("recover", help="salvage a recording whose recorder was killed",
                       description=RECOVER_HELP)
    r.add_argument("recording", metavar="FILE.mcap", help="the unfinished recording (only read)")
    r.add_argument("-o", "--output", required=True, metavar="OUT.mcap",
                   help="the new, finished recording to write")
    r.set_defaults(func=cmd_recover)

    v = sub.add_parser("view", help="show a recorded session (or the live bus) in Rerun",
                       description=VIEW_HELP)
    v.add_argument("recording", nargs="?", metavar="SESSION.mcap",
                   help="the recording (not with --live)")
    where = v.add_mutually_exclusive_group()
    where.add_argument("--rrd", nargs="?", const="", metavar="OUT.rrd",
                       help="write a Rerun file (default: SESSION.rrd beside the MCAP; the "
                            "default when there is no display)")
    where.add_argument("--spawn", action="store_true", help="start a native Rerun viewer")
    where.add_argument("--web", action="store_true", help="start the Rerun web viewer")
    where.add_argument("--connect-viewer", metavar="URL",
                       help="send to a running viewer, e.g. rerun+http://127.0.0.1:9876/proxy")
    v.add_argument("--bind", default="127.0.0.1", metavar="ADDRESS",
                   help="address of the viewer servers this starts (default 127.0.0.1: this "
                        "machine only)")
    v.add_argument("--port", type=int, help="gRPC port of the viewer this starts")
    v.add_argument("--live", action="store_true",
                   help="show every session on the bus as it happens (joins like serve)")
    v.add_argument("--out", default="recordings", metavar="DIR",
                   help="--live without a viewer: where the .rrd files go (default recordings)")
    add_bus_args(v)
    v.set_defaults(func=cmd_view)

    p = sub.add_parser("replay", help="put a recorded session back on the bus",
                       description=REPLAY_HELP)
    p.add_argument("recording", metavar="SESSION.mcap", help="the recording")
    speed = p.add_mutually_exclusive_group()
    speed.add_argument("--rate", type=float, default=1.0,
                       help="speed relative to the recording (default 1.0 = real time)")
    speed.add_argument("--max", action="store_true", help="as fast as the bus takes it")
    p.add_argument("--keys", choices=("inputs", "frames", "all"), default="inputs",
                   help="inputs (default): photos, the recorded choices (run no selection "
                        "service beside) and measurements, so the running services compute "
                        "the rest; frames: photos only; all: every recorded message as it was "
                        "(e.g. for a viewer or recorder)")
    p.add_argument("--session", help="publish under this session id instead")
    p.add_argument("--wait-for", action="append", default=[], metavar="SERVICE",
                   help="start once these services are alive")
    p.add_argument("--timeout", type=float, default=60.0, metavar="S",
                   help="seconds to wait for hypotheses / scenes before going on (default 60)")
    add_bus_args(p)
    p.set_defaults(func=cmd_replay)

    g = sub.add_parser("regress", help="a recording through the current services, every "
                                       "result compared",
                       description=REGRESS_HELP + "\n\n" + COMPARES,
                       formatter_class=argparse.RawDescriptionHelpFormatter)
    g.add_argument("recording", metavar="SESSION.mcap", help="a finished recording")
    g.add_argument("--method", choices=("findme", "paper"),
                   help="hypotheses method (default: the recording's)")
    g.add_argument("--max", type=int, default=10, metavar="N",
                   help="hypotheses per photo (default 10)")
    g.add_argument("--timeout", type=float, default=120.0, metavar="S",
                   help="seconds to wait for each result (default 120)")
    g.add_argument("--json", action="store_true", help="the differences as JSON")
    g.set_defaults(func=cmd_regress)


# ------------------------------------------------------------------------------ recover
def cmd_recover(args) -> int:
    src, dst = Path(args.recording), Path(args.output)
    s = recover(src, dst)
    what = (f"{s.messages} messages ({s.bus_messages} bus messages, "
            f"{s.messages - s.bus_messages} view messages) in {s.chunks} chunks")
    if s.complete:
        print(f"{src} was complete: copied {what} to {dst}")
    else:
        print(f"recovered {what} from {src} into {dst}; dropped the last {s.dropped_bytes} "
              f"bytes (an unfinished chunk or record: {s.reason})")
    return 0


# ------------------------------------------------------------------------------ view
def cmd_view(args) -> int:
    from services.recording.viewer import Sink, has_display
    if args.live:
        return _view_live(args)
    if not args.recording:
        raise InputError("view needs a recording (SESSION.mcap) or --live")
    src = Path(args.recording)
    recs, extent = read_available(src)
    if not extent.complete:
        print(extent.describe(src))
    if args.connect_viewer:
        sink = Sink("connect", url=args.connect_viewer)
    elif args.spawn or args.web:
        sink = Sink("spawn" if args.spawn else "web", bind=args.bind, port=args.port)
    elif args.rrd is not None or not has_display():
        sink = Sink("rrd", path=args.rrd or str(src.with_suffix(".rrd")))
    else:
        sink = Sink("spawn", bind=args.bind, port=args.port)
    where, shown = view_recording(recs, sink)
    print(f"{src}: {shown} messages shown -> {where}")
    if sink.mode == "web":   # the web viewer lives as long as this command: until Ctrl-C
        from services.registry import wait_for_signal
        print("serving the web viewer; Ctrl-C to stop", flush=True)
        try:
            wait_for_signal()
        finally:
            sink.stop()
    return 0


def view_recording(recs: list[Recorded], sink) -> tuple[str, int]:
    """Log a recording's bus messages through the Rerun adapters into ``sink``."""
    from findme_io.rerun_session import SessionView, blueprint
    from services.recording.viewer import new_recording
    if not recs:
        raise RecordingError("the recording holds no Find Me messages")
    session = bus.parse_key(recs[0].key).session
    photos = {bus.parse_key(r.key).index() for r in recs if bus.parse_key(r.key).kind == "frame"}
    rec = new_recording(session)
    where = sink.attach(rec, session, blueprint(photos))
    view = SessionView(rec)
    view.photos = set(photos)                      # the default blueprint already has them
    view._blueprint_for = tuple(sorted(photos))
    shown = 0
    for r in recs:
        try:
            msg = r.message()
        except Exception:  # noqa: BLE001 - a malformed recorded payload: nothing to draw
            continue
        if msg is None:
            continue
        try:
            shown += view.log(msg, r.log_time)
        except InputError:
            continue
    rec.flush()
    rec.disconnect()
    return where, shown


def _view_live(args) -> int:
    from services.registry import wait_for_signal
    from services.runtime.service import Service
    from services.recording.viewer import Sink, ViewerHandler, has_display

    setup_logging()
    if args.connect_viewer:
        sink = Sink("connect", url=args.connect_viewer)
    elif args.spawn or args.web or (has_display() and args.rrd is None):
        sink = Sink("web" if args.web else "spawn", bind=args.bind, port=args.port)
    else:
        sink = Sink("rrd", path=args.rrd or args.out)
    session = open_bus(args)
    svc = Service(ViewerHandler(sink), session).start()
    try:
        wait_for_signal()
    finally:
        svc.stop()
        session.close()
        sink.stop()
    return 0


# ------------------------------------------------------------------------------ replay
def cmd_replay(args) -> int:
    from services.runtime.bus import wait_alive

    setup_logging()
    if args.rate <= 0 or not math.isfinite(args.rate):
        raise InputError(f"--rate must be a positive number, got {args.rate}")
    recs, extent = read_available(args.recording)
    if not extent.complete:
        print(extent.describe(args.recording))
    if not recs:
        raise RecordingError(f"{args.recording}: no Find Me messages to replay")
    if args.session:
        if not schemas.is_valid_session(args.session):
            raise InputError(f"--session {args.session!r} is not a valid session id")
        recs = [rename_session(r, args.session) for r in recs]
    session_id = bus.parse_key(recs[0].key).session
    session = open_bus(args)
    try:
        for name in args.wait_for:
            wait_alive(session, name)
        n = replay(session, recs, keys=args.keys, rate=None if args.max else args.rate,
                   timeout=args.timeout, log=print)
    finally:
        session.close()
    print(f"replayed {n} messages of session {session_id} from {args.recording}")
    return 0


# ------------------------------------------------------------------------------ regress
def cmd_regress(args) -> int:
    import logging

    setup_logging(logging.ERROR)
    r = regress(args.recording, method=args.method, max_n=args.max, timeout=args.timeout)
    if args.json:
        import json
        print(json.dumps({"recording": r.recording, "session": r.session, "ok": r.ok,
                          "compared": r.compared, "differences": r.differences,
                          "notes": r.notes, "tolerances": TOLERANCES}, indent=1))
    else:
        print(r.report())
    return 0 if r.ok else 1
