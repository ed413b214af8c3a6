"""Per-pair diagnosis of the two-photo motions a mapping session relates (issue 16): for every
room set of a findme-eval split (zind-rooms), every pair of photos from two spots with enough
matches for a motion (``session.SessionParams.min_motion_matches``), the motion as the session
estimates it and, with --layouts, as the pair estimator does with the photos' layouts and
appearance; each against the true relative pose.

    python tools/session_pairs.py DATASET_DIR [--layouts] [--rooms zr_r06,zr_r10] [--cache DIR]

Per pair: the error (m, deg), success (yaw <= 5 deg and translation <= 25 % of the true
distance, as score.py scores pairs), the feature inliers, the layout evidence (agreeing wall
samples / violations) and the appearance (correlation / samples). Per room and mode: pairs
right out of answered. ``--cache`` is ``tools/plan_report.py``'s (each room's analysed
photos). The truth is used only to diagnose.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

from findme.evaluation.rooms import room_spots  # noqa: E402
from findme_core.motion import features, methods as motion, photometric as motion_photometric  # noqa: E402
from findme_core.plan import fuse, session
from findme_core.errors import FindmeError  # noqa: E402
from findme_core.motion import features, lifting, methods as motion  # noqa: E402
from findme_core.motion import photometric as motion_photometric  # noqa: E402
from findme_io.imageio import read_image  # noqa: E402
from tools.plan_report import cached_photos  # noqa: E402


def _surfaces(vdir, views, photos):
    out = []
    for v, p in zip(views, photos):
        with open(os.path.join(vdir, v + ".json")) as f:
            meta = json.load(f)
        out.append(motion_photometric.surface(read_image(os.path.join(vdir, meta["image"])),
                                              p.camera, p.layout))
    return out


def _estimate(pa, pb, m, extra):
    def lifter(p, px):
        return None if p.scene is None else (lambda idx: lifting.lift(p.scene, px, idx))
    try:
        return motion.estimate(m, pa.camera, pb.camera, pa.height, pb.height,
                               lifter(pa, m.ua), lifter(pb, m.ub), **extra)
    except FindmeError as e:
        return e


def room_rows(views, photos, truth, surfaces=None, params=session.SessionParams()):
    """One dict per cross-spot pair with a motion: ids, error against ``truth`` ((N, 3)
    true poses) and the motion's evidence, per mode ('session', and 'layouts' when
    ``surfaces`` are given)."""
    spots, rows = room_spots(views, "ids"), []
    for i in range(len(photos)):
        for j in range(i + 1, len(photos)):
            if spots[i] == spots[j]:
                continue
            pa, pb = photos[i], photos[j]
            m = features.match(pa.features, pb.features, params.features)
            if len(m) < params.min_motion_matches:
                continue
            yaw_t, t_t = fuse.relative(truth[i], truth[j])
            row = {"a": views[i], "b": views[j], "matches": len(m),
                   "distance_m": float(np.hypot(*t_t))}
            modes = {"session": {}}
            if surfaces is not None:
                modes["layouts"] = {"layouts": ((pa.layout,) if pa.layout else (),
                                                (pb.layout,) if pb.layout else ()),
                                    "surfaces": (surfaces[i], surfaces[j])}
            for name, extra in modes.items():
                mo = _estimate(pa, pb, m, extra)
                if isinstance(mo, FindmeError):
                    row[name] = {"refused": str(mo)}
                    continue
                et = float(np.hypot(mo.x - t_t[0], mo.z - t_t[1]))
                ey = float(np.degrees(abs(fuse.wrap(mo.yaw - yaw_t))))
                lay = mo.layout
                row[name] = {"err_m": et, "err_deg": ey, "inliers": mo.n_inliers,
                             "ok": ey <= 5 and et <= 0.25 * row["distance_m"],
                             "layout": None if lay is None else (lay.samples, lay.violations),
                             "appearance": mo.appearance,
                             "alternatives": len(mo.alternatives)}
            rows.append(row)
    return rows


def _cell(r):
    if "refused" in r:
        return "refused"
    lay = "-" if r["layout"] is None else f"{r['layout'][0]}/{r['layout'][1]}"
    return (f"{'ok ' if r['ok'] else 'BAD'} {r['err_m']:5.2f} m {r['err_deg']:6.1f} d "
            f"inl {r['inliers']:3d} lay {lay:>7s} app {r['appearance'][0]:+.2f}")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("dataset")
    ap.add_argument("--layouts", action="store_true",
                    help="also the estimate with the photos' layouts and appearance")
    ap.add_argument("--rooms", help="comma-separated room ids (default: all of zind-rooms)")
    ap.add_argument("--cache", metavar="DIR")
    a = ap.parse_args(argv)
    idx = json.load(open(os.path.join(a.dataset, "index.json")))
    rooms = a.rooms.split(",") if a.rooms else idx["subsets"]["zind-rooms"]["rooms"]
    rdir, vdir = os.path.join(a.dataset, "rooms"), os.path.join(a.dataset, "views")
    for rid in rooms:
        room = json.load(open(os.path.join(rdir, rid + ".json")))
        views, photos = cached_photos(rdir, vdir, rid, a.cache)
        truth = np.array([(p["x_m"], p["z_m"], math.radians(p["yaw_deg"]))
                          for p in (room["poses_planar"][v] for v in views)])
        rows = room_rows(views, photos, truth,
                         _surfaces(vdir, views, photos) if a.layouts else None)
        modes = ["session"] + (["layouts"] if a.layouts else [])
        print(f"== {rid}: {len(rows)} pairs across spots")
        for r in rows:
            pair = f"{r['a'][len(rid) + 1:]}->{r['b'][len(rid) + 1:]}"
            print(f"  {pair:16s} {r['distance_m']:4.2f} m  " +
                  "  |  ".join(_cell(r[m]) for m in modes))
        for m in modes:
            ans = [r[m] for r in rows if "refused" not in r[m]]
            print(f"  {m:8s} right {sum(x['ok'] for x in ans)} of {len(ans)} answered "
                  f"({len(rows)} pairs)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
