"""Choose how close a second motion must score to be an alternative
(``MotionParams.alternative_ratio``) leave one room out: every refined motion scoring at least
that fraction of the best one is an alternative, and the answer's 1-sigma spans them
(``motion/alternatives.spread_over``: the variance of their score-weighted mixture).

    python tools/choose_alternatives.py ../shared/data/findme-eval [--ratios 0.3,0.4,...]
        [--param alternative_ratio|rival_sep_deg|scale_ratio] [--gravity given,phone,...]
        [--jobs 2]

``--param rival_sep_deg --ratios 180,45,20,10`` chooses the same way how far a rival must
be turned from the answer (``MotionParams.rival_sep_deg``: the best candidate turned farther
than that is an alternative whatever its score when the matches agree with it at least as
well; 180: never). A tie goes to the highest value there too: no rival.

Every dev pair (all four pair subsets, the dataset's gravity, rank-1 hypotheses, as
``findme eval``) is estimated once per candidate ratio, its photos prepared once. For each
ratio, each pair's x, z and yaw errors are normalised by the stated 1-sigmas; the loss of a
set of pairs is the mean over its subsets (those with >= 10 pairs, so that TUM's 95 pairs do
not outvote ZInD's 22) of the squared distance of their coverage (x, z and yaw pooled) to the
goal: within 1 sigma between 0.60 and 0.80, within 3 sigma at least 0.97. Each group (ZInD
room, TUM block of 6 frames, KITTI) is scored with the ratio whose loss is least on the other
groups (on a tie the highest: the fewest alternatives); the shipped ratio is the one least on
all.
Prints, per ratio, the coverage in sample per subset and the accuracy (medians), then the
leave-one-room-out choice and coverage, and how often an alternative is the right motion
where the best one is wrong. Reads the dataset's ground truth: a tool, not the product.

Measured 2026-11-29 (141 answered pairs, 22 of them wrong): the loss is least at 0.6 in
sample (ZInD level 0.75 / 0.95 within 1 / 3 sigma where 0.8 gives 0.65 / 0.84), but at no
ratio is an alternative the right motion for more than 1 of the 22 wrong answers: a lower
ratio widens the 1-sigma over motions that are as wrong, which covers the wrong answers by
chance. Left out, room06 (most of the wrong answers) takes 0.9, and the held-out coverage is
0.8's. The ratio stays 0.8; this tool is the check. Run again 2026-12-01 with the scale
alternatives (below): least loss at 0.7 in sample (0.0001 against 0.0019 at 0.8; ZInD level
0.74 / 0.89 / 0.96 against 0.68 / 0.86 / 0.89), but left out room06 takes 0.9 and the
held-out figures are 0.8's (level 0.67 / 0.84 / 0.88); at 0.7 (findme eval, the dataset's
gravity) the level pairs' median yaw 1-sigma grows from 1.2 to 3.6 deg (4.7 with a phone's
gravity) and the tilted pairs' median translation 1-sigma from 0.07 to 0.21 of the
baseline, for a right alternative in 3 of the 23 wrong answers against 2. Kept at 0.8.

``--param rival_sep_deg --ratios 180,45,30,20,10``, 2026-11-30 (the rival must also have as
many agreeing matches and about the same appearance correlation as the answer): loss 0.0067
(180: off), 0.0044 (45), 0.0022 (30, 20, 10); answers with alternatives 27 / 30 / 31 / 32 /
32; zind-pairs-level 0.65 / 0.79 / 0.84 -> 0.70 / 0.86 / 0.89 within 1 / 2 / 3 sigma,
zind-pairs-tilted 0.74 / 0.89 / 0.91 -> 0.74 / 0.92 / 0.94, TUM and KITTI unchanged. Chosen:
30; left out, every group takes 30 but room06, which takes 180 (on the other rooms every
value ties), so its held-out figures are those without the rule. The phone's gravity
(findme eval, 1.5 deg noise, refined): all five answers off by 48-180 deg get their rival
and lie within 2.1 sigma in yaw; two right answers are widened (to 40-44 deg).

Again 2026-12-01, ``--gravity given,phone,withheld``, with the matches' counts compared within
their standard error (``alternatives.more_agree``; before: the rival needed at least as many):
loss 0.0107 (180), 0.0034 (45), 0.0036 (30, 20, 10) against 0.0107 / 0.0041 / 0.0044 before;
at 45 zind-pairs-level 0.59 / 0.84 / 0.94 within 1 / 2 / 3 sigma (0.58 / 0.82 / 0.92 before),
zind-pairs-tilted 0.71 / 0.95 / 0.97 (0.69 / 0.92 / 0.95), TUM 0.78 / 0.95 / 0.99 (0.77 / 0.95
/ 0.99); answers with alternatives 157 against 150. Chosen: 45; left out, room06 takes 180.

``--param scale_ratio`` chooses how much of the answer's evidence for its distance a motion
at the same yaw and direction but another distance needs to be an alternative
(``MotionParams.scale_ratio``, ``motion/alternatives.along``); 1.1: never. ``--gravity
given,phone,withheld`` pools the three gravities the product meets (``calibrate_plan
.GRAVITIES``; a pair's three runs are in its room's group). 2026-12-01, 423 answered runs:
loss 0.0069 without (1.1), 0.0039 at 0.1-0.3, 0.0042 at 0.5; a right distance among the
alternatives of the 75 wrong answers 9 -> 12 at 0.3 (13 at 0.1-0.2, with 165-192 answers
widened against 151); within 3 sigma ZInD level 0.90 -> 0.92, tilted 0.92 -> 0.95, KITTI
0.83 -> 0.86, TUM 0.99. Chosen: 0.3; left out, room06 takes 0.5, every other group 0.3.
The raw score's share (rather than the distance's evidence) was tried first: every distance
along the baseline shares its epipolar inliers, so on KITTI candidates 20-50x as far scored
over half the best and widened a 0.5 m motion to +-10 m.
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
from calibrate_plan import GRAVITIES  # noqa: E402
from sigma_coverage import goal_gap, group_of  # noqa: E402
from findme.evaluation.pairs import pair_inputs  # noqa: E402
from findme_core.errors import FindmeError  # noqa: E402
from findme_core.motion.model import MotionParams  # noqa: E402
from findme_core.motion.pair import motion_photos, photo_of  # noqa: E402

SUBSETS = ("zind-pairs-level", "zind-pairs-tilted", "tum-cabinet-pairs", "kitti06-pairs")


def pair_errors(job) -> tuple[str, str, list]:
    """(pair id, subset, per ratio: ((3,) |error| / sigma of x, z, yaw, (2,) the errors
    (metres, degrees), (best right, any alternative right, has alternatives)) or None where
    the motion was refused; right: within 5 deg and 25 % of the baseline, as score.py)."""
    dataset, pid, ratios, param, gravity = job
    cv2.setNumThreads(1)
    pair, photos = pair_inputs(os.path.join(dataset, "pairs"), os.path.join(dataset, "views"),
                               pid, GRAVITIES[gravity])
    g = pair["motion"]
    pa, pb = [photo_of(image, cam, h, 1, "findme", which, gravity_sigma=prov.unsensed_sigma,
                       gravity_alternatives=prov.unsensed_alternatives)
              for (image, cam, h, prov), which in zip(photos, "AB")]
    out = []
    for r in ratios:
        try:
            res = motion_photos(pa, pb, ("findme",), params=MotionParams(**{param: r}))
        except FindmeError:
            out.append(None)
            continue
        m = res["findme"]
        if isinstance(m, FindmeError):
            out.append(None)
            continue
        m = m.motion
        ex, ez = m.x - g["x_m"], m.z - g["z_m"]
        ey = (math.degrees(m.yaw) - g["yaw_deg"] + 180.0) % 360.0 - 180.0
        out.append(([abs(ex) / m.sigma_x, abs(ez) / m.sigma_z,
                     abs(ey) / math.degrees(m.sigma_yaw)], [math.hypot(ex, ez), abs(ey)],
                    (right(m, g), any(right(o, g) for o in m.alternatives),
                     bool(m.alternatives))))
    return pid, pair["subset"], out, gravity


def right(m, g) -> bool:
    """Whether motion ``m`` is within 5 deg and 25 % of the baseline of the truth ``g``."""
    ey = (math.degrees(m.yaw) - g["yaw_deg"] + 180.0) % 360.0 - 180.0
    return abs(ey) <= 5.0 and math.hypot(m.x - g["x_m"], m.z - g["z_m"]) <= 0.25 * math.hypot(
        g["x_m"], g["z_m"])


def coverage(rows, k: int) -> np.ndarray:
    """(3,) within 1, 2, 3 sigma of the answered pairs of ``rows`` at ratio index k, the
    three axes pooled."""
    z = np.array([r[2][k][0] for r in rows if r[2][k] is not None]).ravel()
    return np.array([np.mean(z <= s) for s in (1, 2, 3)]) if len(z) else np.full(3, np.nan)


def loss(rows, k: int) -> float:
    """Mean over the subsets with >= 10 pairs of the squared distance of the coverage to the
    goal (``sigma_coverage.goal_gap``): 0.60-0.80 within 1 sigma, >= 0.97 within 3."""
    parts = []
    for s in SUBSETS:
        sub = [r for r in rows if r[1] == s]
        if len(sub) < 10:
            continue
        c = coverage(sub, k)
        parts.append(goal_gap(c[0], c[2]))
    return float(np.mean(parts)) if parts else float("inf")


def least(rows, ratios) -> int:
    """Index of the ratio of least loss on ``rows``; of equal losses (to 1e-12) the highest
    ratio, the fewest alternatives."""
    ls = np.array([loss(rows, k) for k in range(len(ratios))])
    ok = np.flatnonzero(ls <= ls.min() + 1e-12)
    return int(ok[np.argmax(np.asarray(ratios)[ok])])


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("dataset")
    ap.add_argument("--ratios", default="0.3,0.4,0.5,0.6,0.7,0.8,0.9")
    ap.add_argument("--param", default="alternative_ratio",
                    choices=("alternative_ratio", "rival_sep_deg", "scale_ratio"))
    ap.add_argument("--gravity", default="given",
                    help="comma-separated gravities pooled (calibrate_plan.GRAVITIES: given, "
                         "withheld, phone); a pair's runs are one group")
    ap.add_argument("--jobs", type=int, default=2)
    a = ap.parse_args(argv)
    ratios = [float(x) for x in a.ratios.split(",")]
    idx = json.load(open(os.path.join(a.dataset, "index.json")))
    pids = sorted({p for s in SUBSETS for p in idx["subsets"].get(s, {}).get("pairs", [])})
    gravities = a.gravity.split(",")
    unknown = [g for g in gravities if g not in GRAVITIES]
    if unknown:
        ap.error(f"unknown gravity {unknown[0]!r}; one of {', '.join(GRAVITIES)}")
    jobs = [(a.dataset, p, ratios, a.param, g) for g in gravities for p in pids]
    with ProcessPoolExecutor(a.jobs) as ex:
        rows = list(ex.map(pair_errors, jobs, chunksize=2))
    print("ratio  loss    " + "  ".join(f"{s:>26s}" for s in SUBSETS))
    print("               " + "  ".join(f"{'1/2/3 sigma  t med  yaw med':>26s}"
                                         for _ in SUBSETS))
    for k, r in enumerate(ratios):
        cells = []
        for s in SUBSETS:
            sub = [x for x in rows if x[1] == s]
            c = coverage(sub, k)
            e = np.array([x[2][k][1] for x in sub if x[2][k] is not None])
            cells.append(f"{c[0]:.2f}/{c[1]:.2f}/{c[2]:.2f} {np.median(e[:, 0]):5.3f}m "
                         f"{np.median(e[:, 1]):4.2f}d")
        print(f"{r:5.2f}  {loss(rows, k):.4f}  " + "  ".join(f"{c:>26s}" for c in cells))
    print("ratio  answered  best wrong  with alternatives  best wrong, an alternative right")
    for k, r in enumerate(ratios):
        f = [x[2][k][2] for x in rows if x[2][k] is not None]
        print(f"{r:5.2f}  {len(f):8d}  {sum(not b for b, _, _ in f):10d}  "
              f"{sum(h for _, _, h in f):17d}  {sum((not b) and a for b, a, _ in f):5d}")
    groups = sorted({group_of(x[0]) for x in rows})
    chosen, held = {}, []
    for grp in groups:
        train = [x for x in rows if group_of(x[0]) != grp]
        k = least(train, ratios)
        chosen[grp] = ratios[k]
        held += [(x[0], x[1], [x[2][k]]) for x in rows if group_of(x[0]) == grp]
    best = ratios[least(rows, ratios)]
    print(f"chosen on all pairs: {best:g}; leave-one-room-out: "
          + ", ".join(f"{g} {r:g}" for g, r in chosen.items()))
    print("leave-one-room-out, within 1 / 2 / 3 sigma (x, z, yaw pooled):")
    for s in SUBSETS:
        sub = [x for x in held if x[1] == s]
        c = coverage(sub, 0)
        n = sum(x[2][0] is not None for x in sub)
        print(f"  {s:20s} {c[0]:.2f} / {c[1]:.2f} / {c[2]:.2f}  (n={n} pairs)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
