"""Gravity from the image: time and accuracy on the 640x480 dev views, one core.

    python bench/bench_gravity.py [--json OUT.json]

For every dev view (../shared/data/findme-eval; rendered rooms without it), interleaved
photo by photo in the same run, CPU time of:

* ``vanishing.estimate_gravity`` alone (it detects the photo's whole-frame segments itself);
* the same with the segments given (what a photo without gravity adds to the detection it
  needs anyway: ``photo.hypothesize_without_gravity`` shares it with the hypotheses);
* the joint step ``vanishing.with_floor`` (gravity again, given the best boundary);
* baselines: ``hypothesize`` of the same photo with its gravity (the work gravity is added
  to) and plain Canny + HoughLinesP.

Accuracy: the angle between the estimate and the dataset's gravity (first estimate and
after the joint step; KITTI's gravity is nominal, not measured: left out of the angle),
how often "level" was assumed, and how often the angle lies within the estimate's 1-sigma
(2D: |error| <= 1.515 sigma holds 68 % of the time). Medians with p10 / p90.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import sys
import time

import cv2
import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(__file__), ".."))
from bench.common import canny_hough, dev_photos, fmt, pin_one_core, stats  # noqa: E402
from findme_core.single.methods import hypothesize  # noqa: E402
from findme_core.single.segments import photo_segments  # noqa: E402
from findme_core.single.vanishing import estimate_gravity, with_floor  # noqa: E402

RAYLEIGH_68 = math.sqrt(-2 * math.log(1 - 0.68))


def cpu_ms(fn, *args, **kw):
    t = time.thread_time()
    out = fn(*args, **kw)
    return 1e3 * (time.thread_time() - t), out


def angle_deg(a, b) -> float:
    return math.degrees(math.acos(float(np.clip(a @ b, -1, 1))))


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--json", metavar="OUT.json")
    a = ap.parse_args(argv)
    how = pin_one_core()
    names = ("gravity from the image (with detection)", "gravity, segments given",
             "joint step with the boundary", "baseline: hypothesize (gravity given)",
             "baseline: Canny + HoughLinesP")
    cpu: dict = {k: [] for k in names}
    first, joint, inside, level, n = [], [], [], 0, 0
    for vid, img, cam in dev_photos():
        if n == 0:  # warm up
            estimate_gravity(img, cam)
        n += 1
        t, est = cpu_ms(estimate_gravity, img, cam)
        cpu[names[0]].append(t)
        segs = photo_segments(img)
        cpu[names[1]].append(cpu_ms(estimate_gravity, img, cam, segments=segs)[0])
        t, hs = cpu_ms(hypothesize, img, cam.with_gravity(est.vector), segments=est.segments)
        est2 = est
        if hs.hypotheses:
            t, est2 = cpu_ms(with_floor, est, hs.hypotheses[0].polyline)
            cpu[names[2]].append(t)
        cpu[names[3]].append(cpu_ms(hypothesize, img, cam)[0])
        cpu[names[4]].append(cpu_ms(canny_hough, cv2.cvtColor(img, cv2.COLOR_BGR2GRAY))[0])
        level += est.source == "level"
        if not vid.startswith("kitti"):
            first.append(angle_deg(est.vector, cam.gravity))
            joint.append(angle_deg(est2.vector, cam.gravity))
            if est2.source == "image":
                inside.append(joint[-1] <= RAYLEIGH_68 * math.degrees(est2.sigma))
    print(f"{n} photos, CPU time per photo, interleaved, {how}")
    res = {"cpu": {k: stats(v) for k, v in cpu.items() if v}}
    for k, st in res["cpu"].items():
        print(fmt(k, st))
    for label, ang in (("first estimate", first), ("after the joint step", joint)):
        x = np.asarray(ang)
        res[label] = {"median": float(np.median(x)), "p90": float(np.percentile(x, 90)),
                      "max": float(x.max()), "over_2deg": int((x > 2).sum())}
        print(f"angle to the dataset's gravity, {label}, {len(x)} views: median "
              f"{np.median(x):.2f} deg, p90 {np.percentile(x, 90):.2f}, max {x.max():.1f}, "
              f"over 2 deg {int((x > 2).sum())}")
    res["level_assumed"] = level
    res["within_1sigma"] = float(np.mean(inside)) if inside else None
    print(f"level assumed for {level}; estimates within their 1-sigma: "
          f"{res['within_1sigma']:.2f} (68 % when honest)")
    if a.json:
        with open(a.json, "w") as f:
            json.dump(res, f, indent=1)


if __name__ == "__main__":
    main()
