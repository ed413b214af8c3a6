"""CPU cost of one photo through the whole pipeline, stage by stage, one core.

    python bench/bench_pipeline.py [--json OUT.json] [--repeat 2]

Each 640x480 dev pair (../shared/data/findme-eval: ZInD and TUM pairs; rendered pairs without
the data) is a two-photo session driven through the real service handlers without the bus
(as the services run them): the phone's JPEG bytes in a ``findme.v1.Frame`` (the dataset's
camera and gravity, as a phone sends them) go to hypotheses (decode, lines, search, rank),
selection (auto), measurement (the scene of the chosen hypothesis) and odometry (decode,
features, layouts, the room's orientation, matching, motion, pose); every output is encoded
(``schemas.encode``) and recorded (``McapRecording.write`` with the Foxglove view channels,
as the recorder does). The clock is the thread's CPU time.

A photo in a stream is prepared once for odometry (features and layouts, kept for the next
photo's motion) and closes one motion with the photo before it, so the cost per photo is:
its own stages + the odometry call that prepares it and estimates the motion ending at it.
For the first photo of a pair (no motion of its own) the motion part is the pair's. The
handler is timed as a whole; its parts are timed again with the core calls it makes.

Baselines in the same run: plain Canny + HoughLinesP of the photo (the paper's first step
alone), odometry's motion without the photos' appearance (``photometric_weight`` 0, no
surfaces; the appearance's other part, a photo's surface, is timed on its own), and the
same pipeline without reuse (each motion prepares both its photos: the cost
per photo when features and layouts are not kept between motions). Goal (issue 15): <= 50 ms
CPU per photo median, so that 40 photos/s fit on two cores.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import tempfile
import time
from dataclasses import replace
from pathlib import Path

sys.path.insert(0, os.path.join(os.path.dirname(__file__), ".."))
from bench.common import EVAL_DIR, canny_hough, fmt, pin_one_core, stats  # noqa: E402

import cv2  # noqa: E402

import schemas  # noqa: E402
from findme.evaluation.views import view_inputs  # noqa: E402
from findme_core.motion import photometric as motion_photometric  # noqa: E402
from findme_core.motion.methods import MotionParams  # noqa: E402
from findme_core.motion.pair import prepare  # noqa: E402
from findme_core.motion.photo_lines import photo_lines  # noqa: E402
from findme_io.convert import make_frame  # noqa: E402
from findme_io.imageio import decode_image  # noqa: E402
from services.pipeline.hypotheses import HypothesesHandler  # noqa: E402
from services.pipeline.measurement import MeasurementHandler  # noqa: E402
from services.pipeline.odometry import OdometryHandler  # noqa: E402
from services.pipeline.selection import SelectionHandler  # noqa: E402
from services.recording.mcap_writer import McapRecording  # noqa: E402

CPU = time.thread_time
STAGES = ("hypotheses", "selection", "measurement", "odometry", "encode", "recording")


def pairs():
    """(pair id, [(jpeg bytes, Camera, camera height)] * 2) of the 640x480 dev pairs, or
    rendered pairs (JPEG quality 90) without the data."""
    idx = EVAL_DIR / "index.json"
    if idx.exists():
        index = json.loads(idx.read_text())
        for pid in sorted({p for s in index["subsets"].values() for p in s.get("pairs", [])}):
            pair = json.loads((EVAL_DIR / "pairs" / f"{pid}.json").read_text())
            photos = []
            for which in ("a", "b"):
                meta = json.loads((EVAL_DIR / "views" / f"{pair[which]}.json").read_text())
                cam, h, _ = view_inputs(meta)
                photos.append(((EVAL_DIR / "views" / meta["image"]).read_bytes(), cam, h))
            if all((c.width, c.height) == (640, 480) for _, c, _ in photos):
                yield pid, photos
        return
    from findme_core.synth.render import Pose, Room, render
    room = Room.rectangle(5.0, 6.0, floor_style="carpet")
    for i in range(8):
        out = []
        for dx, dyaw in ((0.0, 0.0), (0.3, 10.0)):
            v = render(room, Pose(0.2 + dx, -1.6, 1.45, yaw_deg=10 * i - 30 + dyaw, pitch_deg=20),
                       640, 480, hfov_deg=70.0, seed=1)
            out.append((cv2.imencode(".jpg", v.image, [cv2.IMWRITE_JPEG_QUALITY, 90])[1].tobytes(),
                        v.camera, v.camera_height))
        yield f"synthetic_{i}", out


def _call(handler, key, msg, acc, stage):
    t0 = CPU()
    outs = handler.on_message(key, msg)
    acc[stage] = acc.get(stage, 0.0) + 1e3 * (CPU() - t0)
    return outs


def run_session(sid: str, photos, rec_dir: Path) -> tuple[list[dict], int]:
    """Drive one session through fresh handlers; per photo {stage: CPU ms}, and the number
    of poses that came out."""
    hyp, sel, meas, odo = HypothesesHandler(), SelectionHandler(), MeasurementHandler(), OdometryHandler()
    rec = McapRecording(rec_dir / f"{sid}.mcap", sid)
    held: dict[str, bytes] = {}
    odo.fetch = held.get      # odometry asks the bus (the store) for a photo's frame
    per, poses = [], 0
    for n, (jpeg, cam, h) in enumerate(photos):
        acc: dict[str, float] = {}
        g = cam.gravity
        frame = make_frame(sid, n, jpeg, intrinsics=(cam.fx, cam.fy, cam.cx, cam.cy, cam.width,
                                                     cam.height), gravity=g, camera_height_m=h)
        fkey = f"findme/{sid}/frame/{n}"
        outs = [(fkey, frame)]
        held[fkey] = schemas.encode(frame)
        for o in _call(hyp, fkey, frame, acc, "hypotheses"):
            outs.append((o.key, o.msg))
            _call(meas, o.key, o.msg, acc, "measurement")
            _call(odo, o.key, o.msg, acc, "odometry")
            if not o.msg.hypotheses:
                raise NoPose(f"photo {n}: {o.msg.reason}")
            for s in _call(sel, o.key, o.msg, acc, "selection"):
                outs.append((s.key, s.msg))
                outs += [(x.key, x.msg) for x in _call(meas, s.key, s.msg, acc, "measurement")]
                res = _call(odo, s.key, s.msg, acc, "odometry")
                outs += [(x.key, x.msg) for x in res]
                poses += sum(1 for x in res if isinstance(x.msg, schemas.Pose))
        t0 = CPU()
        payloads = [(k, schemas.encode(m)) for k, m in outs]
        acc["encode"] = 1e3 * (CPU() - t0)
        t0 = CPU()
        for i, (k, p) in enumerate(payloads):
            rec.write(k, p, time.time_ns() + i)
        acc["recording"] = 1e3 * (CPU() - t0)
        per.append(acc)
    rec.close()
    return per, poses


class NoPose(Exception):
    """A photo without hypotheses (a blank wall without lines): its pair is left out, named."""


def odometry_parts(photos) -> dict[str, float]:
    """CPU ms of what odometry does for a pair, by part, with the core calls its handler
    makes: per photo decode and prepare (features; layouts and the room's orientation from
    the lines the hypotheses sent), then matching, lifting and motion of A -> B."""
    from findme_core.single.methods import hypothesize
    from findme_core.motion.pair import motion_photos
    ins = []
    for jpeg, cam, h in photos:        # hypotheses come from their own stage (not timed here)
        img = decode_image(jpeg, "bench")
        hs = hypothesize(img, cam, "findme", 10)
        # the lines come with the hypotheses (HypothesisSet.lines), as the handler gets them
        ins.append((jpeg, cam, h, hs.hypotheses, photo_lines(hs, img)))
    parts = {"decode": [], "features": [], "layout": []}
    ready = []
    for jpeg, cam, h, hs, lines in ins:
        t0 = CPU()
        img = decode_image(jpeg, "bench")
        parts["decode"].append(1e3 * (CPU() - t0))
        ready.append(prepare(img, cam, h, hs, 1, lines, clock=CPU))
        for k in ("features", "layout"):
            parts[k].append(ready[-1].timing_ms[k])
    res = motion_photos(*ready, ("findme",), clock=CPU)["findme"]
    t = getattr(res, "timing_ms", {})
    # the photos' appearance (motion_photometric): B's surface, and the motion without it
    b, grey = ready[1], cv2.cvtColor(img, cv2.COLOR_BGR2GRAY)   # prepare's grey (shared)
    t0 = CPU()
    motion_photometric.surface(grey, b.camera, b.layouts[0] if b.layouts else None)
    surface_ms = 1e3 * (CPU() - t0)
    bare = motion_photos(*(replace(r, surface=None) for r in ready), ("findme",),
                         params=replace(MotionParams(), photometric_weight=0.0),
                         clock=CPU)["findme"]
    return {"decode": parts["decode"][1], "features": parts["features"][1],
            "layout (walls, orientation)": parts["layout"][1],
            "matching": t.get("matching", float("nan")), "lift": t.get("lift", float("nan")),
            "motion": t.get("motion", float("nan")),
            "motion without appearance": bare.timing_ms["motion"]
            if hasattr(bare, "timing_ms") else float("nan"),
            "appearance: B's surface (in layout)": surface_ms,
            "prepare A": parts["decode"][0] + parts["features"][0] + parts["layout"][0]}


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--json", metavar="OUT.json")
    ap.add_argument("--repeat", type=int, default=2, help="runs per pair, the cheapest kept")
    a = ap.parse_args(argv)
    how = pin_one_core()
    rows: dict[str, list[float]] = {}
    n_pairs = n_poses = 0
    left_out: list[str] = []
    with tempfile.TemporaryDirectory() as tmp:
        for pid, photos in pairs():
            try:
                runs = [run_session(f"bench-{n_pairs}-{r}", photos, Path(tmp))
                        for r in range(a.repeat)]
            except NoPose as e:
                left_out.append(f"{pid} ({e})")
                continue
            per, poses = min(runs, key=lambda run: sum(sum(p.values()) for p in run[0]))
            n_pairs, n_poses = n_pairs + 1, n_poses + poses
            parts = min((odometry_parts(photos) for _ in range(a.repeat)),
                        key=lambda d: sum(v for v in d.values() if v == v))
            # in a stream photo B's odometry call prepares B and moves A -> B, A having been
            # prepared for its own motion before: this session's call also prepares A
            stream_odo = per[1].get("odometry", 0.0) - parts["prepare A"]
            for k, v in parts.items():
                if k != "prepare A" and v == v:
                    rows.setdefault(f"  odometry: {k}", []).append(v)
            for i, p in enumerate(per):
                jpeg = photos[i][0]
                t0 = CPU()
                canny_hough(cv2.cvtColor(decode_image(jpeg, "bench"), cv2.COLOR_BGR2GRAY))
                rows.setdefault("baseline: decode + Canny + HoughLinesP", []).append(1e3 * (CPU() - t0))
                own = sum(p.get(s, 0.0) for s in STAGES if s != "odometry")
                for s in STAGES:
                    rows.setdefault(s, []).append(stream_odo if s == "odometry" else p.get(s, 0.0))
                rows.setdefault("per photo (all stages)", []).append(own + stream_odo)
                rows.setdefault("baseline: per photo without reuse", []).append(
                    own + stream_odo + parts["prepare A"])
    src = "dev split" if (EVAL_DIR / "index.json").exists() else "synthetic"
    print(f"per-photo pipeline on {n_pairs} 640x480 pairs ({src}; {2 * n_pairs} photos, "
          f"{n_poses} poses), cheapest of {a.repeat} runs per pair, {how}, thread CPU ms; "
          f"{len(left_out)} pairs with a photo without hypotheses left out: {', '.join(left_out) or 'none'}")
    out = {k: stats(v) for k, v in rows.items()}
    for k, s in out.items():
        print("  " + fmt(k, s))
    med = out["per photo (all stages)"]["median"]
    print(f"  photos/s on 2 cores at the median: {2000.0 / med:.1f} (goal 40: <= 50 ms)")
    if a.json:
        Path(a.json).write_text(json.dumps(out, indent=1))


if __name__ == "__main__":
    main()
