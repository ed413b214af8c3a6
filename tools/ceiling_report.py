"""Would the ceiling line tell a wrong floor boundary? A failure cue tried and measured.

    python tools/ceiling_report.py ../shared/data/findme-eval [--jobs 2]

The idea (the floor-ceiling symmetry that panorama layout methods use): a wall stands on the
floor line and meets the ceiling at one room height H. Lift each column of the top
hypothesis's WALL pieces to the floor (y = h in the level frame: x right, y down, z
forward; metres), raise it to y = h - H for H in ``HEIGHTS``, project it back, and count the
share of that curve lying on an edge across it (a colour gradient of at least
``MIN_GRADIENT`` levels a pixel within ``ACROSS_DEG`` of the curve's normal): the
best-supported H, if at least ``MIN_SUPPORT`` of the curve, is the room height the boundary
implies. A counter's front edge taken for the floor would imply a room of ~4 m, so an
implausible H would flag the view. On rendered rooms it finds the ceiling height to the
grid's 5 cm, and nothing where no ceiling is in view (``tests/test_tool_ceiling.py``).

Every ZInD dev view, under the dataset's gravity and camera height. A view fails when more
than 30 % of its query points lie beyond 3 sigma (as ``tools/tail_report.py``). The same
search under the TRUE boundary (the dataset's ``boundary_v``) checks the cue itself.

Measured 2026-11-29: 180 views, 16 failing. The failing views show little or no ceiling
(by the dataset's labels at most 5 % of their pixels; under 1 % in 14 of them): they look
down at counters, a stove, carpet. Under their top boundary 14 of the 16 imply no height at
all (no ceiling line found), and the 2 that do imply a plausible one (2.3-3.2 m), while 17
of the 35 other views with an estimate do not: the cue has nothing to say where it is needed.
Under the TRUE boundary, 24 views give a height (median 2.35 m), 62 % of them within
2.3-3.2 m: a ceiling line is found in few real views, and not always the ceiling's. Not used
in the product. (A first version counted Canny edges at 50/150: that misses a ceiling that
differs from its wall in colour more than in brightness, and gave 19 % under the true
boundary.) Reads the dataset's ground truth: a tool, not the product.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
from concurrent.futures import ProcessPoolExecutor

import cv2
import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(__file__), ".."))
from findme_core.single.search import SegKind  # noqa: E402
from tail_report import analyse_view, view_hypotheses  # noqa: E402

#: room heights tried, metres
HEIGHTS = np.arange(1.9, 4.51, 0.05)
#: a plausible home's room height, metres
PLAUSIBLE = (2.3, 3.2)
#: fewest in-image columns for a height to be scored
MIN_COLUMNS = 10
#: an edge: a gradient of at least this many grey levels a pixel, within this angle of the
#: curve's normal; a ceiling line: at least this share of the curve on edges
MIN_GRADIENT, ACROSS_DEG, MIN_SUPPORT = 2.0, 20.0, 0.3


def wall_floor_points(camera, h: float, polyline, kinds) -> np.ndarray:
    """(N, 3) level-frame floor points (metres) under every 2nd column of the WALL pieces of
    ``polyline`` (M, 2) pixels with ``kinds`` (M - 1,), where the boundary is in the image
    and below the horizon; camera height ``h`` metres."""
    poly = np.asarray(polyline, float)
    px = []
    for i in np.nonzero(np.asarray(kinds) == SegKind.WALL)[0]:
        (u0, v0), (u1, v1) = poly[i], poly[i + 1]
        if u1 - u0 >= 1:
            u = np.arange(np.ceil(u0), np.floor(u1) + 1, 2.0)
            px.append(np.column_stack([u, v0 + (u - u0) * (v1 - v0) / (u1 - u0)]))
    if not px:
        return np.zeros((0, 3))
    p = np.concatenate(px)
    p = p[(p[:, 1] >= 0) & (p[:, 1] < camera.height)]
    r = camera.rays_level(p)
    r = r[r[:, 1] > 1e-3]
    return r * (h / r[:, 1])[:, None]


def gradients(image: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(H, W) float32 x and y derivatives (levels a pixel) of the blurred ``image`` (H, W, 3)
    uint8 BGR, each pixel's from the colour channel that changes most there (a grey ceiling
    over a beige wall differs in colour more than in brightness)."""
    blur = cv2.GaussianBlur(image.astype(np.float32), (0, 0), 1.0)
    gx = cv2.Sobel(blur, cv2.CV_32F, 1, 0, ksize=3, scale=0.125)
    gy = cv2.Sobel(blur, cv2.CV_32F, 0, 1, ksize=3, scale=0.125)
    best = np.argmax(gx * gx + gy * gy, axis=2)[..., None]
    return (np.take_along_axis(gx, best, 2)[..., 0], np.take_along_axis(gy, best, 2)[..., 0])


def ceiling_support(grad, camera, h: float, floor_pts: np.ndarray) -> np.ndarray:
    """(len(HEIGHTS),) share of the ceiling curve above ``floor_pts`` (N, 3) that lies on
    an edge across it, for each room height: the gradient ``grad`` ((H, W) x and y) at
    least ``MIN_GRADIENT`` and within ``ACROSS_DEG`` of the curve's normal (a wall meeting
    a ceiling of a similar white is a weak edge, so no fixed edge detector's threshold);
    NaN where fewer than ``MIN_COLUMNS`` of its columns are in the image."""
    gx, gy = grad
    out = np.full(len(HEIGHTS), np.nan)
    for i, H in enumerate(HEIGHTS):
        q = floor_pts.copy()
        q[:, 1] = h - H
        uv, front = camera.project_level(q)
        ok = (front & (uv[:, 0] >= 0) & (uv[:, 0] < camera.width - 1) & (uv[:, 1] >= 1)
              & (uv[:, 1] < camera.height - 1))
        if ok.sum() < MIN_COLUMNS:
            continue
        t = np.gradient(uv, axis=0)[ok]           # the curve's direction at each sample
        normal = np.column_stack([-t[:, 1], t[:, 0]])
        normal /= np.maximum(np.linalg.norm(normal, axis=1, keepdims=True), 1e-9)
        iu, iv = np.rint(uv[ok, 0]).astype(int), np.rint(uv[ok, 1]).astype(int)
        g = np.column_stack([gx[iv, iu], gy[iv, iu]])
        mag = np.linalg.norm(g, axis=1)
        across = np.abs(np.sum(g * normal, axis=1)) >= np.cos(np.radians(ACROSS_DEG)) * mag
        out[i] = float(np.mean((mag >= MIN_GRADIENT) & across))
    return out


def implied_height(support: np.ndarray) -> tuple[float, float]:
    """(best-supported room height m, its support); NaNs when no height was scored or
    none reaches ``MIN_SUPPORT`` (no ceiling line found)."""
    if np.all(np.isnan(support)) or np.nanmax(support) < MIN_SUPPORT:
        return float("nan"), float("nan")
    i = int(np.nanargmax(support))
    return float(HEIGHTS[i]), float(support[i])


def analyse(args):
    """One view: the implied room height under the top and the true boundary, the share of
    ceiling pixels (labels) and the share of its points beyond 3 sigma."""
    dataset, vid = args
    seen = view_hypotheses(dataset, vid, True)
    _, tv = analyse_view((dataset, vid, True), seen) if seen else (vid, None)
    if seen is None or not tv or not tv["points"]:
        return vid, None
    meta, h, _, image, cam, _, hs = seen
    grad = gradients(image)
    top = hs.hypotheses[0]
    out = {"top": implied_height(ceiling_support(
        grad, cam, h, wall_floor_points(cam, h, top.polyline, top.kinds)))}
    bv = np.array([np.nan if b is None else b for b in meta.get("boundary_v") or []], float)
    seen = np.nonzero(np.isfinite(bv))[0]
    out["truth"] = (float("nan"), float("nan"))
    if len(seen) > MIN_COLUMNS:
        poly = np.column_stack([seen, bv[seen]])
        out["truth"] = implied_height(ceiling_support(grad, cam, h, wall_floor_points(
            cam, h, poly, np.full(len(poly) - 1, SegKind.WALL))))
    labels = cv2.imread(os.path.join(dataset, "views", meta["labels"]), cv2.IMREAD_UNCHANGED)
    out["ceiling"] = float(np.mean(labels == 1))
    z = np.concatenate([np.linalg.norm(p["alts"][:, 0] - p["truth"], axis=1) / p["sigma"]
                        for p in tv["points"].values()])
    out["fails"] = bool(np.mean(z > 3) > 0.3)
    return vid, out


def report(res: dict) -> None:
    rows = [r for r in res.values() if r]
    fails = np.array([r["fails"] for r in rows])
    ceiling = np.array([r["ceiling"] for r in rows])
    top_h = np.array([r["top"][0] for r in rows])
    true_h = np.array([r["truth"][0] for r in rows])
    print(f"views {len(rows)}, failing {fails.sum()} (> 30 % of their points beyond 3 sigma)")
    print(f"no ceiling in view (labels < 1 %): {np.sum(ceiling < 0.01)}, failing among them "
          f"{np.sum(fails & (ceiling < 0.01))}; largest ceiling share of a failing view "
          f"{ceiling[fails].max() if fails.any() else float('nan'):.2f}")
    est = np.isfinite(top_h)
    print(f"an implied height under the top boundary: {est.sum()} views, {np.sum(fails & est)} "
          f"of them failing; outside {PLAUSIBLE[0]}-{PLAUSIBLE[1]} m: "
          f"{np.sum(fails & est & ((top_h < PLAUSIBLE[0]) | (top_h > PLAUSIBLE[1])))} failing, "
          f"{np.sum(~fails & est & ((top_h < PLAUSIBLE[0]) | (top_h > PLAUSIBLE[1])))} others")
    t = true_h[np.isfinite(true_h)]
    if len(t):
        ok = np.mean((t >= PLAUSIBLE[0]) & (t <= PLAUSIBLE[1]))
        print(f"under the TRUE boundary: {len(t)} views with an implied height, median "
              f"{np.median(t):.2f} m, {100 * ok:.0f} % of them within {PLAUSIBLE[0]}-"
              f"{PLAUSIBLE[1]} m")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("dataset")
    ap.add_argument("--jobs", type=int, default=2)
    a = ap.parse_args(argv)
    idx = json.load(open(os.path.join(a.dataset, "index.json")))
    views = sorted({v for s in idx["subsets"].values() for v in s.get("views", [])
                    if v.startswith("z")})
    with ProcessPoolExecutor(a.jobs) as ex:
        res = dict(ex.map(analyse, [(a.dataset, v) for v in views], chunksize=2))
    report(res)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
