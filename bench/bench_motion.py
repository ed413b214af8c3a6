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

``--withheld``: the dev pairs as plain photos (no gravity given: each photo's from its lines,
``motion.gravity_spread``), the motion with its gravity tilts beside the same photos' motion
without them (their gravity taken as a sensor's), in the same run.
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


def withheld(repeat: int) -> dict:
    """{row: [ms per pair]}: the motion of the dev pairs from plain photos, with and without
    its gravity tilts (photos prepared once, before the clock)."""
    rows: dict = {}
    idx = EVAL_DIR / "index.json"
    if not idx.exists():
        return rows
    index = json.loads(idx.read_text())
    for pid in sorted({p for s in index["subsets"].values() for p in s.get("pairs", [])}):
        _, photos = pair_inputs(EVAL_DIR / "pairs", EVAL_DIR / "views", pid, False)
        if any((c.width, c.height) != (640, 480) for _, c, _, _ in photos):
            continue
        prepared = [prepare(i, c, h, hypothesize(i, c, "findme", 1, camera_height=h).hypotheses,
                            gravity_sigma=pv.unsensed_sigma) for i, c, h, pv in photos]
        if not any(p.gravity_sigma is not None for p in prepared):
            continue
        best = None
        for _ in range(repeat):
            clock = time.thread_time
            res = motion_photos(*prepared, clock=clock)["findme"]
            sensor = motion_photos(*(replace(p, gravity_sigma=None) for p in prepared),
                                   clock=clock)["findme"]
            if isinstance(res, Exception) or isinstance(sensor, Exception):
                break
            tm = {"motion, gravity taken as a sensor's": sensor.timing_ms["motion"],
                  "motion": res.timing_ms["motion"],
                  "gravity tilts": res.timing_ms.get("gravity_tilts", 0.0)}
            tm["motion + gravity tilts"] = tm["motion"] + tm["gravity tilts"]
            if best is None or tm["motion + gravity tilts"] < best["motion + gravity tilts"]:
                best = tm
        for k, v in (best or {}).items():
            rows.setdefault(k, []).append(v)
    return rows


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--json", metavar="OUT.json")
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--withheld", action="store_true",
                    help="only the pairs as plain photos (gravity from their lines)")
    a = ap.parse_args(argv)
    how = pin_one_core()
    if a.withheld:
        rows = withheld(a.repeat)
        print(f"plain photos (gravity from their lines), {how}, thread CPU time, best of "
              f"{a.repeat} per pair; hypotheses and gravity excluded")
        out = {k: stats(v) for k, v in rows.items()}
        for k, st in out.items():
            print("  " + fmt(k, st))
        if a.json:
            with open(a.json, "w") as f:
                json.dump({"withheld": out}, f, indent=1)
        return
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
