"""Speed of hypothesis generation for 640x480 photos, one core.

    python bench/bench_hypotheses.py [--json OUT.json]

For every 640x480 view of the dev split (../shared/data/findme-eval; falls back to rendered
synthetic rooms without it): our method with the view's gravity, our method on the same
photo without gravity (``photo.hypothesize_without_gravity``: the segments detected once,
gravity from their vanishing directions, the hypotheses from the same segments, gravity again
with the boundary), the paper's method (Hough, level camera), and the baseline "plain
Canny + HoughLinesP" (the paper's first step alone) on the same images, interleaved photo
by photo in the same run. Reports wall-clock and CPU (thread) time: median, p10/p90 and
IQR, the ratios to the baseline and of "no gravity" to "with gravity", and the stages of
both (CPU time). Goal: ours <= 20 ms median, p90 <= 30 ms (about 6x the baseline); a photo
without gravity little more.
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
from bench.common import canny_hough, dev_photos, dev_views, fmt, pin_one_core, stats  # noqa: E402
from findme_core.single.methods import hypothesize  # noqa: E402
from findme_core.single.photo import hypothesize_without_gravity  # noqa: E402


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
    names = ("findme (ours)", "findme, no gravity", "paper method",
             "baseline: Canny + HoughLinesP")
    wall: dict = {k: [] for k in names}
    cpu: dict = {k: [] for k in names}
    parts: dict = {}
    parts_ng: dict = {}
    totals: list = []
    n = 0
    for vid, img, cam in dev_photos():
        gray = cv2.cvtColor(img, cv2.COLOR_BGR2GRAY)
        if n == 0:  # warm up caches and lazy initialisation
            hypothesize(img, cam)
            hypothesize_without_gravity(img, cam)
            hypothesize(img, cam, "paper")
        runs = ((names[0], hypothesize, (img, cam, "findme", 10)),
                (names[1], hypothesize_without_gravity, (img, cam, "findme", 10)),
                (names[2], hypothesize, (img, cam, "paper", 10)),
                (names[3], canny_hough, (gray,)))
        for name, fn, args in runs:
            w, c, _ = timed2(fn, *args)
            wall[name].append(w)
            cpu[name].append(c)
        # stages: CPU time of one more run (thread_time as the pipeline's clock)
        hs = hypothesize(img, cam, "findme", 10, clock=time.thread_time)
        for k, v in hs.timing_ms.items():
            parts.setdefault(k, []).append(v)
        totals.append(sum(hs.timing_ms.values()))
        hs, _ = hypothesize_without_gravity(img, cam, "findme", 10, clock=time.thread_time)
        for k, v in hs.timing_ms.items():
            parts_ng.setdefault(k, []).append(v)
        n += 1
    print(f"hypotheses for {n} 640x480 photos ({'dev split' if dev_views() else 'synthetic'}), "
          f"best of 3 per photo, interleaved, {how}")
    res = {"wall": {k: stats(v) for k, v in wall.items()},
           "cpu": {k: stats(v) for k, v in cpu.items()}}
    for kind in ("wall", "cpu"):
        print(f"-- {kind} time")
        for k, st in res[kind].items():
            print(fmt(k, st))
    for key, ours, base in (("", names[0], names[3]), ("_no_gravity", names[1], names[3]),
                            ("_no_gravity_vs_gravity", names[1], names[0])):
        for kind, d in (("wall", wall), ("cpu", cpu)):
            r = np.asarray(d[ours]) / np.maximum(np.asarray(d[base]), 1e-6)
            res[f"ratio{key}_{kind}"] = {
                "of_medians": res[kind][ours]["median"] / res[kind][base]["median"],
                "median_per_photo": float(np.median(r)), "p90_per_photo": float(np.percentile(r, 90))}
            q = res[f"ratio{key}_{kind}"]
            print(f"{ours} / {base} ({kind}): {q['of_medians']:.2f}x of the medians, "
                  f"{q['median_per_photo']:.2f}x median per photo (p90 {q['p90_per_photo']:.2f}x)")
    res["stages_cpu"] = {k: stats(v) for k, v in parts.items()}
    res["stages_cpu_no_gravity"] = {k: stats(v) for k, v in parts_ng.items()}
    for label, key in (("ours", "stages_cpu"), ("ours without gravity", "stages_cpu_no_gravity")):
        print(f"{label} by stage, CPU ms (median [p10, p90]): " + ", ".join(
            f"{k} {s_['median']:.1f} [{s_['p10']:.1f}, {s_['p90']:.1f}]"
            for k, s_ in res[key].items()))
    res["stages_cpu_total"] = stats(totals)
    print(fmt("sum of the stages (CPU)", res["stages_cpu_total"]))
    if a.json:
        with open(a.json, "w") as f:
            json.dump(res, f, indent=1)


if __name__ == "__main__":
    main()
