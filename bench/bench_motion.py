"""Speed of the two-image mode for 640x480 pairs, one core.

    python bench/bench_motion.py [--json OUT.json] [--repeat 3]

For every dev pair whose two views are 640x480 (../shared/data/findme-eval: the ZInD and TUM
pairs; rendered synthetic pairs without it): feature extraction of both photos, their
layouts (walls of the candidate hypotheses, the room's orientation from the hypotheses'
lines), matching, and the motion (lifting the matched points under each photo's rank-1
hypothesis, then the estimator), with the chosen detector and matcher (ORB, 3000 keypoints
spread on a grid, FLANN-LSH matching) side by side with the alternatives (exact brute-force
matching of the same keypoints, ORB with 1500 keypoints, SIFT with 3000) in the same run,
and the feature-only estimator (the default before layouts), the paper's estimator and ours
without the photos' appearance (the default before it, ``photometric_weight`` 0, photos
prepared without their surfaces) next to ours on the chosen features. Hypotheses are
computed before the clock starts (~40-60 ms per photo, their own benchmark). Per pair the best of ``--repeat`` runs; reports median,
p10/p90 and IQR over the pairs, in CPU milliseconds of the (one) thread, which other
processes on the machine do not inflate. Goal: features + matching + motion <= 60 ms.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from dataclasses import replace


sys.path.insert(0, os.path.join(os.path.dirname(__file__), ".."))
from bench.common import EVAL_DIR, fmt, pin_one_core, stats  # noqa: E402
from findme.evaluation.pairs import pair_inputs  # noqa: E402
from findme_core.motion.features import FeatureParams  # noqa: E402
from findme_core.motion.methods import MotionParams  # noqa: E402
from findme_core.motion.pair import motion_photos, prepare  # noqa: E402
from findme_core.single.methods import hypothesize  # noqa: E402
from findme.evaluation.pairs import pair_inputs  # noqa: E402

DETECTORS = {
    "orb 3000 grid, lsh matching (chosen)": FeatureParams(),
    "orb 3000 grid, exact matching": FeatureParams(matcher="brute"),
    "orb 1500 grid": FeatureParams(n_features=1500),
    "sift 3000": FeatureParams(detector="sift", grid=None),
}


def pairs():
    """(pair id, image A, image B, camera A, camera B, h A, h B) of the 640x480 dev pairs, or
    rendered synthetic pairs without the data."""
    idx = EVAL_DIR / "index.json"
    if idx.exists():
        index = json.loads(idx.read_text())
        for pid in sorted({p for s in index["subsets"].values() for p in s.get("pairs", [])}):
            _, photos = pair_inputs(EVAL_DIR / "pairs", EVAL_DIR / "views", pid)
            if all((c.width, c.height) == (640, 480) for _, c, _, _ in photos):
                (ia, ca, ha, _), (ib, cb, hb, _) = photos
                yield pid, ia, ib, ca, cb, ha, hb
        return
    from findme_core.synth.render import Box, Pose, Room, render
    room = Room.rectangle(5.0, 6.0, floor_style="carpet", boxes=(Box(1.0, 1.6, 0.8, 0.5, 0.9, 20),))
    for i in range(8):
        a = render(room, Pose(0.2, -1.6, 1.45, yaw_deg=10 * i - 30, pitch_deg=20), 640, 480,
                   hfov_deg=70.0, seed=1)
        b = render(room, Pose(0.5, -1.2, 1.45, yaw_deg=10 * i - 20, pitch_deg=22), 640, 480,
                   hfov_deg=70.0, seed=1)
        yield f"synthetic_{i}", a.image, b.image, a.camera, b.camera, 1.45, 1.45


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--json", metavar="OUT.json")
    ap.add_argument("--repeat", type=int, default=3)
    a = ap.parse_args(argv)
    how = pin_one_core()
    runs: dict = {}
    n, answered = 0, {}
    params = MotionParams()
    for pid, ia, ib, ca, cb, ha, hb in pairs():
        # hypotheses (and their lines) are computed once, before the clock
        hsa, hsb = (hypothesize(i, c, "findme", params.max_layouts) for i, c in ((ia, ca), (ib, cb)))
        for name, fp in DETECTORS.items():
            methods = ("findme", "features", "paper") if "chosen" in name else ("findme",)
            best = None
            for _ in range(a.repeat):
                clock = time.thread_time   # CPU time: steady on a shared machine
                pa = prepare(ia, ca, ha, hsa.hypotheses, 1, hsa.lines.ends, params.max_layouts,
                             fp, clock)
                pb = prepare(ib, cb, hb, hsb.hypotheses, 1, hsb.lines.ends, params.max_layouts,
                             fp, clock)
                res = motion_photos(pa, pb, methods, fp, params, clock)
                if "chosen" in name:   # main's default before the photos' appearance took part
                    res["findme without appearance"] = motion_photos(
                        replace(pa, surface=None), replace(pb, surface=None), ("findme",), fp,
                        replace(params, photometric_weight=0.0), clock)["findme"]
                ours = res["findme"]
                if isinstance(ours, Exception):     # no estimate: time up to the error
                    break
                tm = dict(ours.timing_ms)
                for other in ("findme without appearance", "features", "paper"):
                    if other in res and not isinstance(res[other], Exception):
                        tm[f"{other} estimator (motion)"] = res[other].timing_ms["motion"]
                if best is None or sum(tm.values()) < sum(best.values()):
                    best = tm
            if best is None:
                continue
            answered[name] = answered.get(name, 0) + 1
            core = best["features"] + best["layout"] + best["matching"] + best["lift"] + best["motion"]
            rows = [("features", best["features"]), ("layout (walls, orientation)", best["layout"]),
                    ("matching", best["matching"]), ("lift (3D)", best["lift"]),
                    ("motion", best["motion"]),
                    ("features + matching + motion", core)]
            rows += [(k, v) for k, v in best.items() if k.endswith("estimator (motion)")]
            for k, v in rows:
                runs.setdefault(name, {}).setdefault(k, []).append(v)
        n += 1
    src = "dev split" if (EVAL_DIR / "index.json").exists() else "synthetic"
    print(f"two-image mode on {n} 640x480 pairs ({src}), best of {a.repeat} per pair, {how}, "
          "thread CPU time; hypotheses excluded; 'features + matching + motion' includes the "
          "layouts and lifting")
    out = {}
    for name, parts in runs.items():
        print(f"-- {name}: estimate for {answered.get(name, 0)} of {n} pairs")
        out[name] = {k: stats(v) for k, v in parts.items()}
        for k, s in out[name].items():
            print("  " + fmt(k, s))
    if a.json:
        with open(a.json, "w") as f:
            json.dump(out, f, indent=1)


if __name__ == "__main__":
    main()
