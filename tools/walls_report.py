"""Per-point diagnosis of the wall 3D points under the top hypothesis (issue 14).

For every ZInD view of a findme-eval split: the top hypothesis (as ``findme eval`` makes it),
its scene, and for each ground-truth wall point a row: relative error, the predicted surface,
and why it may be off:

* ``base``: whether the point's column shows the base of the point's OWN wall (the label just
  above the true boundary is 10 + the point's wall), the base of another wall (a door /
  opening below it: 100+ / 200+, or another wall), or no floor at all (``none``);
* ``dv``: predicted minus true boundary row in the point's column (pixels; None when either
  is missing);
* ``deg``: how far below the horizon the true boundary is in that column (degrees);
* the predicted segment kind of the column (WALL / STEP / OPEN / NONE).

    python tools/walls_report.py DATASET [--no-gravity | --gravity-noise DEG] [--gravity-refine]
                                 [--gravity-sigma DEG] [--subsets a,b] [--csv OUT.csv]
                                 [--max-rel-sigma X | --max-rel-sigma none]

Prints per subset the median relative error (answered points), the coverage, the share below
10 % (missing = failure, as score.py) and, per cause, the points and their median error;
``reason``: why a point has no answer (``Scene``'s reason, or "no hypothesis").
"""

from __future__ import annotations

import argparse
import csv
import json
import math
import os
import sys
from concurrent.futures import ProcessPoolExecutor

import cv2
import numpy as np

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

from findme.cli.evaluate import add_gravity_args  # noqa: E402
from findme.evaluation.views import GravityInput, view_camera, view_inputs  # noqa: E402
from findme_core.errors import FindmeError  # noqa: E402
from findme_core.single.scene import MAX_REL_SIGMA, Scene, boundary_sigma_px  # noqa: E402
from findme_core.single.search import SegKind  # noqa: E402
from findme_io.camera_source import hypothesize_photo  # noqa: E402
from findme_io.imageio import read_image  # noqa: E402

ZIND = ("zind-level", "zind-level-lowfloor", "zind-tilted", "zind-pairs-level",
        "zind-pairs-tilted", "zind-rooms")


def _kind_at(poly, kinds, u):
    s = int(np.clip(np.searchsorted(poly[1:, 0], u, side="left"), 0, len(kinds) - 1))
    return SegKind(int(kinds[s])).name, float(np.interp(u, poly[:, 0], poly[:, 1]))


def _cross(a, b):
    return float(a[0] * b[1] - a[1] * b[0])


def _visible(poly, kinds, u, H):
    """(in-image length in px of the collinear WALL run holding column u, u distance from
    its in-image part) -- how much of the point's wall base is seen, how far it is carried."""
    s = int(np.clip(np.searchsorted(poly[1:, 0], u, side="left"), 0, len(kinds) - 1))
    if kinds[s] != SegKind.WALL:
        return None, None

    def direction(k):
        d = poly[k + 1] - poly[k]
        return d / max(np.hypot(*d), 1e-9)
    lo = hi = s
    while lo > 0 and kinds[lo - 1] == SegKind.WALL and abs(_cross(direction(lo - 1), direction(lo))) < 0.01:
        lo -= 1
    while hi < len(kinds) - 1 and kinds[hi + 1] == SegKind.WALL and abs(_cross(direction(hi), direction(hi + 1))) < 0.01:
        hi += 1
    us = np.linspace(poly[lo, 0], poly[hi + 1, 0], 400)
    vs = np.interp(us, poly[:, 0], poly[:, 1])
    inside = (vs >= -0.5) & (vs <= H - 0.5)
    if not inside.any():
        return 0.0, float(min(abs(u - poly[lo, 0]), abs(u - poly[hi + 1, 0])))
    pts = np.column_stack([us, vs])[inside]
    length = float(np.hypot(*np.diff(pts, axis=0).T).sum())
    a, b = pts[:, 0].min(), pts[:, 0].max()
    return round(length, 1), float(max(a - u, u - b, 0.0))


def view_rows(args):
    view_dir, vid, subset, gravity, max_rel = args
    cv2.setNumThreads(1)
    with open(os.path.join(view_dir, vid + ".json")) as f:
        meta = json.load(f)
    if not meta.get("wall_points"):
        return []
    _, h, queries = view_inputs(meta)
    image = read_image(os.path.join(view_dir, meta["image"]))
    labels = cv2.imread(os.path.join(view_dir, meta["labels"]), cv2.IMREAD_UNCHANGED)
    cam, prov = view_camera(meta, image, gravity)
    hs, cam, prov = hypothesize_photo(image, cam, prov, "findme", 10, camera_height=h)
    scene = None
    if hs.hypotheses:
        top = hs.hypotheses[0]
        try:
            scene = Scene(cam, h, top.polyline, top.kinds, gravity_cov=prov.gravity_cov,
                          boundary_sigma_px=boundary_sigma_px(cam.width, cam.height),
                          max_rel_sigma=max_rel)
        except FindmeError:
            scene = None
    pts = meta["wall_points"]
    located = scene.locate([q["px"] for q in pts]) if scene is not None else [None] * len(pts)
    fy, cy = meta["intrinsics"]["fy"], meta["intrinsics"]["cy"]
    pitch = math.radians(meta.get("pitch_deg") or 0.0)
    rows = []
    for q, loc in zip(pts, located):
        u, v = q["px"]
        bv = meta["boundary_v"][u]
        if bv is None:
            base = "none"
        else:
            lab = int(labels[max(bv - 1, 0), u]) if bv > 0 else -1
            base = ("own" if lab == 10 + q["wall"] else
                    "aperture" if 100 <= lab < 300 else
                    "top" if bv == 0 else "other")
        g = np.asarray(q["xyz_m"], float)
        err = None
        surf = None
        reason = ("no hypothesis" if loc is None else
                  None if loc.xyz is not None else loc.error.split(":")[0][:40])
        if loc is not None and loc.xyz is not None:
            err = 100.0 * float(np.linalg.norm(loc.xyz - g) / np.linalg.norm(g))
            surf = loc.surface
        kind, pv = (None, None) if scene is None else _kind_at(scene.polyline, scene.kinds, u)
        vis, ext = (None, None) if scene is None else _visible(scene.polyline, scene.kinds, u, cam.height)
        deg = None if bv is None else math.degrees(math.atan2(bv - cy, fy) + pitch)
        rows.append({"subset": subset, "view": vid, "u": u, "v": v, "wall": q["wall"],
                     "base": base, "true_bv": bv, "pred_v": None if pv is None else round(pv, 1),
                     "dv": None if (pv is None or bv is None) else round(pv - bv, 1),
                     "kind": kind, "deg": None if deg is None else round(deg, 2),
                     "surface": surf, "reason": reason, "err_pct": None if err is None else round(err, 2),
                     "sigma_m": None if loc is None or loc.xyz is None else round(loc.sigma_m, 3),
                     "vis_px": vis, "ext_px": ext, "dist_m": round(float(np.linalg.norm(g)), 3)})
    return rows


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("dataset")
    add_gravity_args(ap)
    ap.add_argument("--subsets", default=",".join(ZIND))
    ap.add_argument("--csv")
    ap.add_argument("--jobs", type=int, default=os.cpu_count() or 1)
    ap.add_argument("--max-rel-sigma", default=str(MAX_REL_SIGMA),
                    help="Scene.max_rel_sigma ('none': every point answered)")
    a = ap.parse_args()
    with open(os.path.join(a.dataset, "index.json")) as f:
        index = json.load(f)
    view_dir = os.path.join(a.dataset, index.get("views_dir", "views"))
    max_rel = None if a.max_rel_sigma.lower() == "none" else float(a.max_rel_sigma)
    gravity = GravityInput.from_args(a)
    jobs = [(view_dir, v, s, gravity, max_rel) for s in a.subsets.split(",")
            for v in index["subsets"][s].get("views", [])]
    with ProcessPoolExecutor(a.jobs) as ex:
        rows = [r for rs in ex.map(view_rows, jobs, chunksize=2) for r in rs]
    if a.csv:
        with open(a.csv, "w", newline="") as f:
            w = csv.DictWriter(f, fieldnames=list(rows[0]))
            w.writeheader()
            w.writerows(rows)
    for s in a.subsets.split(","):
        R = [r for r in rows if r["subset"] == s]
        if not R:
            continue
        e = [r["err_pct"] for r in R if r["err_pct"] is not None]
        ok10 = sum(x < 10 for x in e) / len(R)
        print(f"{s:22s} n={len(R):5d} cov={len(e) / len(R):.2f} med={np.median(e) if e else float('nan'):6.2f}% "
              f"p90={np.percentile(e, 90) if e else float('nan'):7.1f}% <10%={ok10:.2f}")
        for key in ("base", "kind", "surface", "reason"):
            cats = sorted({str(r[key]) for r in R})
            parts = []
            for c in cats:
                rc = [r for r in R if str(r[key]) == c]
                ec = [r["err_pct"] for r in rc if r["err_pct"] is not None]
                parts.append(f"{c}: n={len(rc)} ans={len(ec)} med={np.median(ec) if ec else float('nan'):.1f}%")
            print(f"    {key:8s} " + " | ".join(parts))
    return 0


if __name__ == "__main__":
    sys.exit(main())
