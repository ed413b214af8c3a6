"""How good the gravity and the 1-sigma values of a ``findme eval`` run are, per subset.

    python tools/gravity_report.py DATASET_DIR PREDICTIONS.json [--json OUT.json]

For every view: the angle between the gravity the prediction used (``gravity_cam``) and the
dataset's ``gravity_cam`` (median, p90, max; how many came from the image and how many were
assumed level), and whether that angle lies within the prediction's 1-sigma (for a 2D
isotropic error of per-axis sigma s, |error| <= 1.515 s holds 68 % of the time). For every
3D point with a prediction: the fraction whose true error is within its ``sigma_m`` (the
"coverage"; about 68 % when the sigmas are honest), for floor, wall and non-floor points,
also without the camera-height term of the sigma (the dataset's heights are exact, while
the sigma assumes a height the user typed, 1-sigma ``DEFAULT_HEIGHT_SIGMA_M``; that term
alone makes the floor points' coverage look conservative). Last row: every view once.
Run it on ``findme eval --no-gravity`` output to score the estimate, on a normal run to see
the sigmas with the given gravity. Reads the dataset's ground truth: a tool, not the product.
"""

from __future__ import annotations

import argparse
import json
import math
import os

import numpy as np

KINDS = ("floor_points", "wall_points", "nonfloor_points")
#: |2D isotropic gaussian| <= RAYLEIGH_68 * per-axis sigma with probability 0.68
RAYLEIGH_68 = math.sqrt(-2 * math.log(1 - 0.68))


def report(dataset: str, preds: dict) -> dict:
    idx = json.load(open(os.path.join(dataset, "index.json")))
    vdir = os.path.join(dataset, idx.get("views_dir", "views"))
    out = {}
    subsets = [(name, ss.get("views", [])) for name, ss in idx["subsets"].items()]
    subsets.append(("all views", sorted({v for _, vids in subsets for v in vids})))
    for name, vids in subsets:
        if not vids:
            continue
        ang, inside, sources = [], [], {}
        cover = {k: [] for k in KINDS}
        cover_nh = {k: [] for k in KINDS}
        rel = {k: [] for k in KINDS}
        for v in vids:
            meta = json.load(open(os.path.join(vdir, v + ".json")))
            p = preds.get("views", {}).get(v)
            if not p or "gravity_cam" not in p:
                continue
            g, t = np.asarray(p["gravity_cam"], float), np.asarray(meta["gravity_cam"], float)
            a = math.degrees(math.acos(float(np.clip(g @ t / np.linalg.norm(g) / np.linalg.norm(t), -1, 1))))
            ang.append(a)
            src = p.get("gravity_source", "?")
            sources[src] = sources.get(src, 0) + 1
            s = p.get("gravity_sigma_deg")
            if s is not None:
                inside.append(a <= RAYLEIGH_68 * s)
            for k in KINDS:
                xs, ss_ = p.get(k) or [], p.get(k + "_sigma_m") or []
                parts = p.get(k + "_sigma_parts_m") or [None] * len(xs)
                for q, x, sg, sp in zip(meta.get(k) or [], xs, ss_, parts):
                    if x is None or sg is None:
                        continue
                    err = float(np.linalg.norm(np.subtract(x, q["xyz_m"])))
                    cover[k].append(err <= sg)
                    if sp is not None:   # views.SIGMA_PARTS in quadrature, height left out
                        cover_nh[k].append(err <= math.hypot(sp[0], *sp[2:]))
                    rel[k].append(sg / max(np.linalg.norm(q["xyz_m"]), 1e-9))
        if not ang:
            continue
        a = np.asarray(ang)
        out[name] = {"views": len(a), "sources": sources,
                     "angle_deg": {"median": float(np.median(a)), "p90": float(np.percentile(a, 90)),
                                   "max": float(a.max())},
                     "gravity_within_1sigma": float(np.mean(inside)) if inside else None,
                     "points_within_1sigma": {k: (float(np.mean(c)), len(c)) for k, c in cover.items() if c},
                     "points_within_1sigma_no_height": {k: float(np.mean(c))
                                                        for k, c in cover_nh.items() if c},
                     "median_rel_sigma": {k: float(np.median(r)) for k, r in rel.items() if r}}
    return out


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("dataset")
    ap.add_argument("predictions")
    ap.add_argument("--json", metavar="OUT.json")
    a = ap.parse_args(argv)
    res = report(a.dataset, json.load(open(a.predictions)))
    print(f"{'subset':22s} {'views':>5s}  gravity angle deg: median   p90    max   within 1-sigma"
          "   sources                      3D points within 1-sigma / without the height term (n)")
    for name, r in res.items():
        ad = r["angle_deg"]
        src = ", ".join(f"{k} {n}" for k, n in sorted(r["sources"].items()))
        nh = r["points_within_1sigma_no_height"]
        cov = "  ".join(f"{k.split('_')[0]} {c:.2f}" + (f"/{nh[k]:.2f}" if k in nh else "") + f" ({n})"
                        for k, (c, n) in r["points_within_1sigma"].items())
        g1 = "n/a" if r["gravity_within_1sigma"] is None else f"{r['gravity_within_1sigma']:.2f}"
        print(f"{name:22s} {r['views']:5d}  {ad['median']:24.2f} {ad['p90']:6.2f} {ad['max']:6.2f}"
              f"   {g1:>14s}   {src:28s} {cov}")
    if a.json:
        json.dump(res, open(a.json, "w"), indent=1)


if __name__ == "__main__":
    main()
