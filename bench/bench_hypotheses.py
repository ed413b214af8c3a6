"""Speed of hypothesis generation for 640x480 photos, one core.

    python bench/bench_hypotheses.py [--json OUT.json]

For every 640x480 view of the dev split (../shared/data/findme-eval; falls back to rendered
synthetic rooms without it): our method, the paper's method (Hough, level camera), and the
baseline "plain Canny + HoughLinesP" (the paper's first step alone) on the same images,
interleaved photo by photo in the same run. Reports wall-clock and CPU (thread) time: median,
p10/p90 and IQR, the ratio to the baseline, and our stages (CPU time). Goal: ours <= 20 ms
median, p90 <= 30 ms (about 6x the baseline).
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time

import cv2
import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(__file__), ".."))
from bench.common import EVAL_DIR, dev_views, fmt, pin_one_core, stats  # noqa: E402
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


def timed2(fn, *args, repeat: int = 3):
    """(best wall ms, best CPU ms, result) of ``repeat`` runs of fn(*args)."""
    best_w = best_c = float("inf")
    out = None
    for _ in range(repeat):
        w0, c0 = time.perf_counter(), time.thread_time()
        out = fn(*args)
        best_c = min(best_c, time.thread_time() - c0)
        best_w = min(best_w, time.perf_counter() - w0)
    return best_w * 1e3, best_c * 1e3, out


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--json", metavar="OUT.json")
    a = ap.parse_args(argv)
    how = pin_one_core()
    names = ("findme (ours)", "paper method", "baseline: Canny + HoughLinesP")
    wall: dict = {k: [] for k in names}
    cpu: dict = {k: [] for k in names}
    parts: dict = {}
    totals: list = []
    n = 0
    for vid, img, cam in images():
        gray = cv2.cvtColor(img, cv2.COLOR_BGR2GRAY)
        if n == 0:  # warm up caches and lazy initialisation
            hypothesize(img, cam)
            hypothesize(img, cam, "paper")
        runs = ((names[0], hypothesize, (img, cam, "findme", 10)),
                (names[1], hypothesize, (img, cam, "paper", 10)),
                (names[2], canny_hough, (gray,)))
        for name, fn, args in runs:
            w, c, _ = timed2(fn, *args)
            wall[name].append(w)
            cpu[name].append(c)
        # stages: CPU time of one more run (thread_time as the pipeline's clock)
        hs = hypothesize(img, cam, "findme", 10, clock=time.thread_time)
        for k, v in hs.timing_ms.items():
            parts.setdefault(k, []).append(v)
        totals.append(sum(hs.timing_ms.values()))
        n += 1
    print(f"hypotheses for {n} 640x480 photos ({'dev split' if dev_views() else 'synthetic'}), "
          f"best of 3 per photo, interleaved, {how}")
    res = {"wall": {k: stats(v) for k, v in wall.items()},
           "cpu": {k: stats(v) for k, v in cpu.items()}}
    for kind in ("wall", "cpu"):
        print(f"-- {kind} time")
        for k, st in res[kind].items():
            print(fmt(k, st))
    base = names[2]
    for kind, d in (("wall", wall), ("cpu", cpu)):
        r = np.asarray(d[names[0]]) / np.maximum(np.asarray(d[base]), 1e-6)
        res[f"ratio_{kind}"] = {"of_medians": res[kind][names[0]]["median"] / res[kind][base]["median"],
                                "median_per_photo": float(np.median(r))}
        print(f"ours / baseline ({kind}): {res[f'ratio_{kind}']['of_medians']:.2f}x of the medians, "
              f"{res[f'ratio_{kind}']['median_per_photo']:.2f}x median per photo")
    res["stages_cpu"] = {k: stats(v) for k, v in parts.items()}
    print("ours by stage, CPU ms (median [p10, p90]): " + ", ".join(
        f"{k} {s_['median']:.1f} [{s_['p10']:.1f}, {s_['p90']:.1f}]"
        for k, s_ in res["stages_cpu"].items()))
    res["stages_cpu_total"] = stats(totals)
    print(fmt("sum of the stages (CPU)", res["stages_cpu_total"]))
    if a.json:
        with open(a.json, "w") as f:
            json.dump(res, f, indent=1)


if __name__ == "__main__":
    main()
