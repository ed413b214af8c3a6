"""Gravity from the image: time and accuracy on the 640x480 dev views, one core.

    python bench/bench_gravity.py

For every dev view (../shared/data/findme-eval; rendered rooms without it): CPU time of
``findme_core.vanishing.estimate_gravity`` next to ``hypothesize`` of the same photo (the
work it is added to when a photo comes without gravity), and the angle between the
estimate and the dataset's gravity (KITTI's gravity is nominal, not measured: left out of
the angle). Medians with p10 / p90.
"""

from __future__ import annotations

import math
import os
import sys
import time

import cv2
import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(__file__), ".."))
from bench.common import EVAL_DIR, dev_views, fmt, pin_one_core, stats  # noqa: E402
from findme.evaluate import view_inputs  # noqa: E402
from findme_core.methods import hypothesize  # noqa: E402
from findme_core.vanishing import estimate_gravity  # noqa: E402


def cpu_ms(fn, *args):
    t = time.process_time()
    out = fn(*args)
    return 1e3 * (time.process_time() - t), out


def main():
    how = pin_one_core()
    views = dev_views()
    items = []
    if views:
        for vid, meta in views:
            cam, _, _ = view_inputs(meta)
            items.append((vid, cv2.imread(str(EVAL_DIR / "views" / meta["image"])), cam))
    else:
        from findme_core.synth import Pose, Room, render
        room = Room.rectangle(5.0, 6.0)
        for i in range(12):
            v = render(room, Pose(0.2, -1.5, 1.45, yaw_deg=-60 + 10 * i, pitch_deg=5 * (i % 4)),
                       640, 480, hfov_deg=75.0, seed=i)
            items.append((f"synthetic_{i}", v.image, v.camera))
    grav, hyp, ang, level = [], [], [], 0
    estimate_gravity(items[0][1], items[0][2])     # warm up
    for vid, img, cam in items:
        t, est = cpu_ms(estimate_gravity, img, cam)
        grav.append(t)
        hyp.append(cpu_ms(hypothesize, img, cam)[0])
        level += est.source == "level"
        if not vid.startswith("kitti"):
            ang.append(math.degrees(math.acos(float(np.clip(est.vector @ cam.gravity, -1, 1)))))
    print(f"{len(items)} photos 640x480, CPU time per photo, {how}")
    print(fmt("gravity from the image", stats(grav)))
    print(fmt("baseline: hypothesize (same photo)", stats(hyp)))
    a = np.asarray(ang)
    print(f"angle to the dataset's gravity over {len(a)} views: median {np.median(a):.2f} deg, "
          f"p90 {np.percentile(a, 90):.2f}, max {a.max():.1f}; level assumed for {level}")


if __name__ == "__main__":
    main()
