"""Choose the weight of gravity's alternatives (``vanishing.GravityParams.alternative_weight``)
leave one room out: a frame scoring at least ``ambiguity_ratio`` of the best one, more than
``distinct_deg`` away, is an alternative that widens the estimate's 1-sigma as a mixture in
which it weighs ``weight`` x its score ratio (``single/gravity_alternatives.widen``): how often
an alternative that strong is in fact the right frame.

    python tools/choose_ambiguity.py ../shared/data/findme-eval [--weights 0.1,0.2,...]

Every dev view's refined frames (gravity withheld; the first stage of ``estimate_gravity``:
the search and its refinements, before the floor step) are scored once; for each candidate
ratio the estimate's 1-sigma is widened over its alternatives and the pitch and roll errors
normalised by it. The weight is the odds that a flagged view's alternative, not its best
frame, is the right one (``frequency``: among the views with an alternative, the share whose
best frame is more than ``distinct_deg`` off while an alternative is within it, taken at the
upper end of its 95 % interval: the dev rooms have few such views), per unit of score ratio;
the coverage loss (the squared gap to the goal, 0.60-0.80 within 1 sigma and >= 0.97 within 3,
``sigma_coverage.goal_gap``) is printed beside it, flat on the dev rooms. Each room (TUM:
block of 6 frames) is scored with the weight estimated on the others; the shipped weight is
estimated on all. The ratio itself is not chosen here: the dev rooms hold too few wrong
frames to tell 0.8 from 0.9 (the table shows them), and a photo of floorboards turns a lower
one into a confident wrong tilt. Reads the dataset's ground truth: a tool, not the product.
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
from sigma_coverage import goal_loss, group_of  # noqa: E402
from findme_core.geometry.camera import Camera  # noqa: E402
from findme_core.geometry.manhattan import pitch_roll_deg, refine, score_frames, search  # noqa: E402
from findme_core.single import gravity_alternatives as alt  # noqa: E402
from findme_core.single import vanishing as V  # noqa: E402
from findme_core.single.segments import photo_segments  # noqa: E402

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


def normalised(views, ratio: float, distinct_deg: float,
               weight: float = 1.0) -> tuple[np.ndarray, np.ndarray]:
    """(|pitch error| / sigma and |roll error| / sigma of each view whose best frame is
    usable, whether the view was made ambiguous, once per axis)."""
    z, amb = [], []
    for _, truth, fr in views:
        if not fr or fr[0][2] is None:
            continue
        g, s0, cov = np.array(fr[0][0]), fr[0][1], np.array(fr[0][2])
        alts = alt.distinct(g, s0, [(np.array(f[0]), f[1]) for f in fr[1:]], ratio, distinct_deg)
        c = alt.widen(g, cov, alts, weight)
        sig = math.degrees(math.sqrt(max(np.trace(c), 0.0) / 2.0))
        p, r = pitch_roll_deg(alt.down(g))
        pt, rt = pitch_roll_deg(alt.down(np.array(truth)))
        z += [abs(p - pt) / sig, abs((r - rt + 180) % 360 - 180) / sig]
        amb += [bool(alts)] * 2
    return np.array(z), np.array(amb)


def frequency_weight(views, ratio: float, distinct_deg: float) -> tuple[float, int, int]:
    """(weight, flagged views, of which an alternative was the right frame): the weight w
    with w x (the flagged views' mean summed ratio) / (1 + the same) = that share's upper
    95 % bound (``wilson_upper``)."""
    flagged, alt_right, sums = 0, 0, []
    for _, truth, fr in views:
        if not fr or fr[0][2] is None:
            continue
        g, s0 = np.array(fr[0][0]), fr[0][1]
        alts = alt.distinct(g, s0, [(np.array(f[0]), f[1]) for f in fr[1:]], ratio, distinct_deg)
        if not alts:
            continue
        flagged += 1
        sums.append(sum(r for _, r in alts))
        t = np.array(truth)
        if (alt.angle_deg(g, t) > distinct_deg
                and min(alt.angle_deg(a, t) for a, _ in alts) <= distinct_deg):
            alt_right += 1
    if not flagged:
        return 1.0, 0, 0
    f = min(wilson_upper(alt_right, flagged), 0.98)
    return f / ((1.0 - f) * float(np.mean(sums))), flagged, alt_right


def wilson_upper(k: int, n: int, z: float = 1.96) -> float:
    """The upper end of the Wilson score interval (95 %) of a share k / n: with a few
    flagged views the share is barely known, so the widening takes its upper bound."""
    p = k / n
    c = (p + z * z / (2 * n) + z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n)))
    return c / (1 + z * z / n)


def loss(views, ratio: float, distinct_deg: float, weight: float) -> float:
    """The coverage's gap to the goal (``sigma_coverage.goal_loss``) at this weight."""
    return goal_loss(normalised(views, ratio, distinct_deg, weight)[0])


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("dataset")
    ap.add_argument("--weights", default="0.05,0.1,0.2,0.35,0.5,0.75,1.0")
    ap.add_argument("--ratio", type=float, default=V.GravityParams.ambiguity_ratio)
    ap.add_argument("--distinct-deg", type=float, default=V.GravityParams.distinct_deg)
    ap.add_argument("--jobs", type=int, default=2)
    a = ap.parse_args(argv)
    idx = json.load(open(os.path.join(a.dataset, "index.json")))
    vids = sorted({v for n, ss in idx["subsets"].items() for v in ss.get("views", [])
                   if not n.startswith("kitti")})
    with ProcessPoolExecutor(a.jobs) as ex:
        views = list(ex.map(frames, [(a.dataset, v) for v in vids], chunksize=4))
    weights = [float(x) for x in a.weights.split(",")]
    groups = sorted({group_of(v) for v, _, _ in views})
    chosen, held_z, held_amb = {}, [], []
    for g in groups:
        train = [v for v in views if group_of(v[0]) != g]
        w = frequency_weight(train, a.ratio, a.distinct_deg)[0]
        chosen[g] = w
        z, amb = normalised([v for v in views if group_of(v[0]) == g], a.ratio, a.distinct_deg,
                            w)
        held_z += list(z)
        held_amb += list(amb)
    best, flagged, right = frequency_weight(views, a.ratio, a.distinct_deg)
    print(f"ratio {a.ratio:g}: {flagged} views with an alternative, {right} of them with the "
          f"right frame among the alternatives, not the best: weight {best:.3f}")
    print(f"ratio {a.ratio:g}: weight  loss   within 1 / 2 / 3 sigma (pitch and roll)  "
          "ambiguous")
    for w in weights:
        z, amb = normalised(views, a.ratio, a.distinct_deg, w)
        print(f"  {w:5.2f}  {loss(views, a.ratio, a.distinct_deg, w):.4f}  "
              + " / ".join(f"{np.mean(z <= k):.2f}" for k in (1, 2, 3)) + f"   {np.mean(amb):.2f}")
    print("weight 1, other ratios:")
    for r in (0.75, 0.8, 0.85, 0.9, 0.95):
        z, amb = normalised(views, r, a.distinct_deg, 1.0)
        print(f"  ratio {r:4.2f}  " + " / ".join(f"{np.mean(z <= k):.2f}" for k in (1, 2, 3))
              + f"   ambiguous {np.mean(amb):.2f}")
    z, amb = np.array(held_z), np.array(held_amb)
    print(f"estimated on all views: weight {best:.3f}; leave-one-room-out: "
          + ", ".join(f"{g} {w:.3f}" for g, w in chosen.items()))
    print("leave-one-room-out: within 1 / 2 / 3 sigma "
          + " / ".join(f"{np.mean(z <= k):.2f}" for k in (1, 2, 3))
          + f", ambiguous {np.mean(amb):.2f} (n={len(z)})")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
