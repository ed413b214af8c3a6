"""Choose gravity's ambiguity ratio (``vanishing.GravityParams.ambiguity_ratio``) leave one room
out: a frame scoring at least that share of the best one, more than ``distinct_deg`` away, is
an alternative that widens the estimate's 1-sigma (``single/gravity_alternatives``).

    python tools/choose_ambiguity.py ../shared/data/findme-eval [--ratios 0.75,0.8,...]

Every dev view's refined frames (gravity withheld; the first stage of ``estimate_gravity``:
the search and its refinements, before the floor step) are scored once; for each candidate
ratio the estimate's 1-sigma is widened over its alternatives and the pitch and roll errors
normalised by it. A ratio's loss on a set of views: the squared gap of its coverage within 1
and 3 sigma to a Gaussian's (0.68, 0.99 at least) plus the share of views made ambiguous
times ``COST`` (an ambiguous photo measures nothing: its points get no answer). Each room
(TUM: block of 6 frames) is scored with the ratio chosen on the others; the shipped ratio is
chosen on all. Reads the dataset's ground truth: a tool, not the product.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import sys
from concurrent.futures import ProcessPoolExecutor

import cv2
import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(__file__), ".."))
sys.path.insert(0, os.path.dirname(__file__))
from sigma_coverage import group_of  # noqa: E402
from findme_core.geometry.camera import Camera  # noqa: E402
from findme_core.geometry.manhattan import pitch_roll_deg, refine, score_frames, search  # noqa: E402
from findme_core.single import gravity_alternatives as alt  # noqa: E402
from findme_core.single import vanishing as V  # noqa: E402
from findme_core.single.segments import photo_segments  # noqa: E402

#: loss per share of views made ambiguous (their points go unanswered)
COST = 0.05


def frames(job):
    """(view, truth gravity, [(gravity, score, tilt covariance or None)] best first)."""
    dataset, vid = job
    cv2.setNumThreads(1)
    meta = json.load(open(os.path.join(dataset, "views", vid + ".json")))
    k = meta["intrinsics"]
    cam = Camera(k["fx"], k["fy"], k["cx"], k["cy"], k["width"], k["height"])
    img = cv2.imread(os.path.join(dataset, "views", meta["image"]))
    p = V.GravityParams()
    seg = photo_segments(img)
    s = seg.width / img.shape[1]
    K = (cam.scaled(s) if abs(s - 1) > 1e-12 else cam).K
    L, _ = V._lines(seg, K, p)
    out = []
    if len(L) >= 3:
        found = search(L, K, p.pitch_range, p.roll_range, p.coarse_lines, p.inlier_deg, p.peaks,
                       p.coarse_deg, p.fine_deg, p.span_deg, p.fine_lines,
                       max(p.candidates, p.ambiguity_candidates), p.candidate_ratio)
        done = [refine(L, K, R, p.inlier_deg, p.iterations, p.min_line_sigma_deg) for R in found]
        if done:
            sc, _ = score_frames(L, K, np.array([d[0][:, 1] for d in done]), p.inlier_deg)
            for (R, cov, masks), s_ in zip(done, sc):
                e = V._estimate(R, cov, masks, p, None, None)
                out.append((e.vector.tolist(), float(s_),
                            None if e.source != "image" else e.cov.tolist()))
            first = out[:p.candidates]
            k = int(np.argmax([f[1] for f in first]))
            out = [out[k]] + [f for i, f in enumerate(out) if i != k]
    return vid, meta["gravity_cam"], out


def normalised(views, ratio: float, distinct_deg: float) -> tuple[np.ndarray, np.ndarray]:
    """(|pitch error| / sigma and |roll error| / sigma of each view whose best frame is
    usable, whether the view was made ambiguous, once per axis)."""
    z, amb = [], []
    for _, truth, fr in views:
        if not fr or fr[0][2] is None:
            continue
        g, s0, cov = np.array(fr[0][0]), fr[0][1], np.array(fr[0][2])
        alts = alt.distinct(g, s0, [(np.array(f[0]), f[1]) for f in fr[1:]], ratio, distinct_deg)
        c = alt.widen(g, cov, alts)
        sig = math.degrees(math.sqrt(max(np.trace(c), 0.0) / 2.0))
        p, r = pitch_roll_deg(alt.down(g))
        pt, rt = pitch_roll_deg(alt.down(np.array(truth)))
        z += [abs(p - pt) / sig, abs((r - rt + 180) % 360 - 180) / sig]
        amb += [bool(alts)] * 2
    return np.array(z), np.array(amb)


def loss(views, ratio: float, distinct_deg: float) -> float:
    z, amb = normalised(views, ratio, distinct_deg)
    c1, c3 = float(np.mean(z <= 1)), float(np.mean(z <= 3))
    return (c1 - 0.68) ** 2 + (min(c3, 0.99) - 0.99) ** 2 + COST * float(np.mean(amb))


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("dataset")
    ap.add_argument("--ratios", default="0.7,0.75,0.8,0.85,0.9,0.95,1.01")
    ap.add_argument("--distinct-deg", type=float, default=V.GravityParams.distinct_deg)
    ap.add_argument("--jobs", type=int, default=2)
    a = ap.parse_args(argv)
    idx = json.load(open(os.path.join(a.dataset, "index.json")))
    vids = sorted({v for n, ss in idx["subsets"].items() for v in ss.get("views", [])
                   if not n.startswith("kitti")})
    with ProcessPoolExecutor(a.jobs) as ex:
        views = list(ex.map(frames, [(a.dataset, v) for v in vids], chunksize=4))
    ratios = [float(x) for x in a.ratios.split(",")]
    groups = sorted({group_of(v) for v, _, _ in views})
    chosen, held_z, held_amb = {}, [], []
    for g in groups:
        train = [v for v in views if group_of(v[0]) != g]
        r = min(ratios, key=lambda x: (round(loss(train, x, a.distinct_deg), 9), x))
        chosen[g] = r
        z, amb = normalised([v for v in views if group_of(v[0]) == g], r, a.distinct_deg)
        held_z += list(z)
        held_amb += list(amb)
    best = min(ratios, key=lambda x: (round(loss(views, x, a.distinct_deg), 9), x))
    print("ratio  loss   within 1 / 2 / 3 sigma (pitch and roll)  ambiguous")
    for r in ratios:
        z, amb = normalised(views, r, a.distinct_deg)
        print(f"{r:5.2f}  {loss(views, r, a.distinct_deg):.4f}  "
              + " / ".join(f"{np.mean(z <= k):.2f}" for k in (1, 2, 3)) + f"   {np.mean(amb):.2f}")
    z, amb = np.array(held_z), np.array(held_amb)
    print(f"chosen on all views: {best:g}; leave-one-room-out choices: "
          + ", ".join(f"{g} {r:g}" for g, r in chosen.items()))
    print("leave-one-room-out: within 1 / 2 / 3 sigma "
          + " / ".join(f"{np.mean(z <= k):.2f}" for k in (1, 2, 3))
          + f", ambiguous {np.mean(amb):.2f} (n={len(z)})")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
