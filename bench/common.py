"""Helpers shared by the benchmarks: one-core pinning, timing, and statistics."""

from __future__ import annotations

import json
import os
import time
from pathlib import Path

# one core means one thread: numpy's BLAS threads would share the pinned core (set before
# numpy is first imported; the benchmarks import this module first)
for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")

import numpy as np  # noqa: E402

from findme.malloc_env import keep_freed_memory  # noqa: E402

# glibc's allocator as findme's processes run it: the compute bound and every stage's CPU
# are measured as the services spend them
keep_freed_memory()

EVAL_DIR = Path(os.environ.get("FINDME_EVAL_DIR",
                               Path(__file__).resolve().parents[2] / "shared" / "data" / "findme-eval"))


def pin_one_core() -> str:
    """Run on one CPU core with OpenCV single-threaded; returns a description."""
    import cv2
    cv2.setNumThreads(1)
    try:
        core = sorted(os.sched_getaffinity(0))[-1]
        os.sched_setaffinity(0, {core})
        return f"pinned to core {core}, cv2 threads 1"
    except (AttributeError, OSError):
        return "cv2 threads 1 (no affinity control)"


def timed(fn, *args, repeat: int = 1) -> tuple[float, object]:
    """(best-of-``repeat`` milliseconds, result) of fn(*args)."""
    best, out = float("inf"), None
    for _ in range(repeat):
        t0 = time.perf_counter()
        out = fn(*args)
        best = min(best, time.perf_counter() - t0)
    return best * 1e3, out


def stats(ms) -> dict:
    a = np.asarray(ms, float)
    return {"n": int(len(a)), "median": float(np.median(a)), "p10": float(np.percentile(a, 10)),
            "p90": float(np.percentile(a, 90)), "iqr": float(np.subtract(*np.percentile(a, [75, 25])))}


def fmt(name: str, s: dict, unit: str = "ms") -> str:
    return (f"{name:34s} median {s['median']:7.2f} {unit}   p10 {s['p10']:7.2f}   "
            f"p90 {s['p90']:7.2f}   IQR {s['iqr']:6.2f}   (n={s['n']})")


def dev_views(size=(640, 480)):
    """(view id, meta) of every dev view of the given image size, or [] without the data."""
    idx_path = EVAL_DIR / "index.json"
    if not idx_path.exists():
        return []
    index = json.loads(idx_path.read_text())
    vids = sorted({v for s in index["subsets"].values() for v in s.get("views", [])})
    out = []
    for v in vids:
        meta = json.loads((EVAL_DIR / "views" / f"{v}.json").read_text())
        k = meta["intrinsics"]
        if (k["width"], k["height"]) == size:
            out.append((v, meta))
    return out


def dev_photos():
    """(id, BGR image, Camera) of every 640x480 dev view (the dataset's gravity), or of 12
    rendered rooms when the dataset is absent."""
    import cv2
    from findme.evaluation.views import view_inputs
    views = dev_views()
    if views:
        for vid, meta in views:
            cam, _, _ = view_inputs(meta)
            yield vid, cv2.imread(str(EVAL_DIR / "views" / meta["image"])), cam
        return
    from findme_core.synth.render import Pose, Room, render
    room = Room.rectangle(5.0, 6.0)
    for i in range(12):
        v = render(room, Pose(0.2, -1.5, 1.45, yaw_deg=-60 + 10 * i, pitch_deg=5 * (i % 4)),
                   640, 480, hfov_deg=75.0, seed=i)
        yield f"synthetic_{i}", v.image, v.camera


def canny_hough(gray):
    """The baseline: plain Canny + HoughLinesP (the paper's first step alone)."""
    import cv2
    return cv2.HoughLinesP(cv2.Canny(gray, 50, 150), 1, np.pi / 180, 40, minLineLength=28,
                           maxLineGap=4)
