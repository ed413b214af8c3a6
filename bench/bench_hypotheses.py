"""Speed of hypothesis generation for 640x480 photos, one core.

    python bench/bench_hypotheses.py [--json OUT.json]

For every 640x480 view of the dev split (../shared/data/findme-eval; falls back to rendered
synthetic rooms without it): our method, the paper's method (Hough, level camera), and the
baseline "plain Canny + HoughLinesP" (the paper's first step alone) on the same images in
the same run. Reports median, p10/p90 and IQR. Goal: ours <= 20 ms median.
"""

from __future__ import annotations

import argparse
import json
import os
import sys

import cv2
import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(__file__), ".."))
from bench.common import EVAL_DIR, dev_views, fmt, pin_one_core, stats, timed  # noqa: E402
from findme.evaluate import view_inputs  # noqa: E402
from findme_core.methods import hypothesize  # noqa: E402


def canny_hough(gray):
    return cv2.HoughLinesP(cv2.Canny(gray, 50, 150), 1, np.pi / 180, 40, minLineLength=28,
                           maxLineGap=4)


def images():
    views = dev_views()
    if views:
        for vid, meta in views:
            cam, _, _ = view_inputs(meta)
            yield vid, cv2.imread(str(EVAL_DIR / "views" / meta["image"])), cam
        return
    from findme_core.synth import Pose, Room, render
    room = Room.rectangle(5.0, 6.0)
    for i in range(12):
        v = render(room, Pose(0.2, -1.5, 1.45, yaw_deg=-60 + 10 * i, pitch_deg=5 * (i % 4)),
                   640, 480, hfov_deg=75.0, seed=i)
        yield f"synthetic_{i}", v.image, v.camera


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--json", metavar="OUT.json")
    a = ap.parse_args(argv)
    how = pin_one_core()
    runs = {"findme (ours)": [], "paper method": [], "baseline: Canny + HoughLinesP": []}
    parts: dict = {}
    n = 0
    for vid, img, cam in images():
        gray = cv2.cvtColor(img, cv2.COLOR_BGR2GRAY)
        if n == 0:  # warm up caches and lazy initialisation
            hypothesize(img, cam)
            hypothesize(img, cam, "paper")
        t, hs = timed(lambda: hypothesize(img, cam, "findme", 10,
                                          clock=__import__("time").perf_counter), repeat=3)
        runs["findme (ours)"].append(t)
        for k, v in hs.timing_ms.items():
            parts.setdefault(k, []).append(v)
        runs["paper method"].append(timed(hypothesize, img, cam, "paper", 10, repeat=3)[0])
        runs["baseline: Canny + HoughLinesP"].append(timed(canny_hough, gray, repeat=3)[0])
        n += 1
    print(f"hypotheses for {n} 640x480 photos ({'dev split' if dev_views() else 'synthetic'}), "
          f"best of 3 per photo, {how}")
    res = {k: stats(v) for k, v in runs.items()}
    for k, s in res.items():
        print(fmt(k, s))
    print("ours by stage (median ms): " + ", ".join(f"{k} {np.median(v):.1f}" for k, v in parts.items()))
    if a.json:
        json.dump({"runs": res, "stages": {k: stats(v) for k, v in parts.items()}}, open(a.json, "w"), indent=1)


if __name__ == "__main__":
    main()
