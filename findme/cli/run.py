"""``findme run``: every service in this process on one Zenoh session (the default
deployment): photos (default: the bundled example) -> hypotheses -> selection -> scenes,
motion and trajectory, printed as they arrive (``findme.report``); then a measurement query.
"""

from __future__ import annotations

import logging
import uuid
from pathlib import Path

from services.pipeline.capture import CaptureHandler
from services.registry import add_service_args, make_handler
from services.runtime.service import Group

from ..report import Printer, example_paths, measure, read_photos, report_session
from .bus_options import add_bus_args, lens_from_args, open_bus, setup_logging
from .options import add_camera_args, finite_float, said_points

PIPELINE = ("hypotheses", "selection", "measurement", "odometry", "mapper")

RUN_HELP = """\
Every service in this one process, on the bundled example pair (two rendered
photos of a room, with their true values printed beside the answers) or on your
photos, files, folders or a video: each photo's boundary hypotheses, the one
selected, its 3D scene, the motion between photos and where each was taken, the
room's floor plan, then a measurement. The session is recorded to
OUT/<session>.mcap (default findme-run/). Without a camera height (options or
PHOTO.json beside a photo) lengths are in camera heights (h).

Examples:  findme run
           findme run kitchen/*.jpg --camera-height 1.45 --interactive"""


def register(sub) -> None:
    r = sub.add_parser("run", help="every service in this process, on the example or your photos",
                       description=RUN_HELP)
    r.add_argument("photos", nargs="*", metavar="PHOTO",
                   help="image files, folders, a video or camera:N "
                                             "(default: the bundled example)")
    r.add_argument("--session", help="session id (default: a new one, run-<random>)")
    add_camera_args(r)
    r.add_argument("--camera-height", type=finite_float, metavar="M",
                   help="camera height above the floor in metres (default: PHOTO.json's, else "
                        "unknown: lengths in camera heights)")
    r.add_argument("--measure", action="append", metavar="U,V[,floor|wall|top]",
                   help="a pixel of photo 0 to measure at the end (repeatable); with floor, "
                        "wall or top: the surface you say it is on (top: the top of something "
                        "standing on the floor line below it, with its height)")
    add_service_args(r, out_help="where the session is recorded (default findme-run)")
    r.add_argument("--no-record", action="store_true",
                   help="do not record the session (default: <out>/<session>.mcap)")
    add_bus_args(r)
    r.set_defaults(func=cmd_run, out="findme-run")


def cmd_run(args) -> int:
    setup_logging(logging.WARNING)
    session_id = args.session or f"run-{uuid.uuid4().hex[:6]}"
    photos = args.photos or example_paths()
    Path(args.out).mkdir(parents=True, exist_ok=True)
    srcs, errors = read_photos(photos)   # read and validate every photo before starting
    pixels, said = said_points(args.measure or [], "--measure")
    session = open_bus(args)
    group = Group(session)
    printer = Printer(session_id)
    sub = session.declare_subscriber(f"findme/{session_id}/**", printer)
    recorder = None
    try:
        if not args.no_record:  # first in, so stopped last: it records everything
            from services.recording.recorder import RecorderHandler
            recorder = group.add(RecorderHandler(args.out)).handler
        capture = group.add(CaptureHandler())
        names = []
        for name in PIPELINE:
            try:
                names.append(group.add(make_handler(name, args)).handler.name)
            except ImportError:  # a service whose module is not installed
                continue
        report_session(printer, capture, session_id, srcs, lens_from_args(args), "odometry" in names, 600,
                       "mapper" in names)
        measure(session, session_id, pixels, example=not args.photos, said=said,
                scene=printer.seen.get(f"findme/{session_id}/scene/0"))
    finally:
        sub.undeclare()
        group.stop()
        session.close()
    if recorder is not None and recorder.path_of(session_id):
        print(f"recording: {recorder.path_of(session_id)}")
    return 2 if errors else 0
