"""``findme export``: a recorded session's trajectory for other tools.

    findme export SESSION.mcap [--tum OUT.txt] [--csv OUT.csv]

* ``--tum``: the TUM RGB-D format (``timestamp tx ty tz qx qy qz qw``, findme_core/
  trajectory.py), which evo reads (``evo_traj tum OUT.txt``, ``evo_ape tum truth.txt
  OUT.txt``).
* ``--csv``: ``index, time_ns, time_utc, x_m, z_m, yaw_deg, sigma_x_m, sigma_z_m,
  sigma_yaw_deg, photo`` with a header line.

Poses are the session's last ``trajectory`` (else its ``pose/<n>`` messages): photo n's
level frame in the session frame (the level frame of the first photo; x right, z ahead,
y down; yaw > 0 turned right), metres. The bus carries planar poses, so ty = 0. Timestamps
are capture times: the pose's own (odometry copies it from the frame), else its frame's
``capture_time_ns`` (EXIF time of a photo file, the phone's clock for a page upload, a
video's frame time: services/pipeline/capture.py), never when a service handled it.
"""

from __future__ import annotations

import datetime as dt
import math
from pathlib import Path

from findme_core.errors import RecordingError
from findme_core.motion.trajectory import PlanarPose, to_tum
from services.recording.mcap_reader import read_available


EXPORT_HELP = """\
A recorded session's camera path, for other tools: where each photo was taken,
in the first photo's level frame (x right, z ahead, metres; yaw > 0 turned
right), at its capture time (the photo's EXIF time, else when it was captured).
A recording still being written is read as far as it is complete (it says how
far).

  --tum  the TUM RGB-D format, "timestamp tx ty tz qx qy qz qw" (seconds,
         metres), which evo reads: evo_traj tum OUT.txt
  --csv  index, time_ns, time_utc, x_m, z_m, yaw_deg, their 1-sigma and the
         photo's name, with a header line

Example:  findme export recordings/s.mcap --tum trajectory.txt"""


def register(sub) -> None:
    p = sub.add_parser("export", help="a recorded session's camera path as TUM (evo) or CSV",
                       description=EXPORT_HELP)
    p.add_argument("recording", metavar="SESSION.mcap", help="the recording")
    p.add_argument("--tum", metavar="OUT.txt", help="write the TUM trajectory (evo reads it)")
    p.add_argument("--csv", metavar="OUT.csv", help="write the poses as CSV")
    p.set_defaults(func=cmd_export)


def session_poses(path, recs=None) -> list[tuple[int, int, object, str]]:
    """(index, capture time ns, Pose message, photo name) of every pose of a recording
    (``recs``: its messages, already read), by index.

    Raises:
        RecordingError: the recording has no pose, or a pose has no capture time.
    """
    frames, poses, trajectory = {}, {}, None
    for r in (read_available(path)[0] if recs is None else recs):
        kind = r.key.split("/")[2] if r.key.count("/") >= 2 else ""
        if kind not in ("frame", "pose", "trajectory"):
            continue
        m = r.message()
        if m is None:
            continue
        if kind == "frame":
            frames[m.index] = m
        elif kind == "pose":
            poses[m.index] = m
        else:
            trajectory = m
    if trajectory is not None and trajectory.poses:
        poses = {**poses, **{p.index: p for p in trajectory.poses}}
    if not poses:
        raise RecordingError(f"{path}: no poses in this recording (did odometry run? a "
                             "session needs two photos with a motion between them)")
    out = []
    for n in sorted(poses):
        f = frames.get(n)
        t = poses[n].time_ns or (f.capture_time_ns if f is not None else 0)
        if not t:
            raise RecordingError(f"{path}: photo {n} has a pose but no capture time")
        out.append((n, t, poses[n], f.device if f is not None else ""))
    return out


def tum_text(rows) -> str:
    return to_tum([PlanarPose(p.x_m, 0.0, p.z_m, p.yaw_rad) for _, _, p, _ in rows],
                  [t for _, t, _, _ in rows])


def csv_text(rows) -> str:
    import csv
    import io
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(["index", "time_ns", "time_utc", "x_m", "z_m", "yaw_deg", "sigma_x_m",
                "sigma_z_m", "sigma_yaw_deg", "photo"])

    def opt(p, name, scale=1.0):
        return f"{getattr(p, name) * scale:.6f}" if p.HasField(name) else ""
    for n, t, p, photo in rows:
        utc = dt.datetime.fromtimestamp(t / 1e9, dt.timezone.utc).isoformat(timespec="milliseconds")
        w.writerow([n, t, utc, f"{p.x_m:.6f}", f"{p.z_m:.6f}", f"{math.degrees(p.yaw_rad):.4f}",
                    opt(p, "sigma_x_m"), opt(p, "sigma_z_m"),
                    opt(p, "sigma_yaw_rad", 180 / math.pi), photo])
    return buf.getvalue()


def cmd_export(args) -> int:
    from findme_core.errors import InputError
    if not args.tum and not args.csv:
        raise InputError("export needs --tum OUT.txt and/or --csv OUT.csv")
    recs, extent = read_available(args.recording)
    if not extent.complete:
        print(extent.describe(args.recording))
    rows = session_poses(args.recording, recs)
    for path, text in ((args.tum, tum_text), (args.csv, csv_text)):
        if path:
            Path(path).write_text(text(rows))
            print(f"{path}: {len(rows)} poses")
    return 0
