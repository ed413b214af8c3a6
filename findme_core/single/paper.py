"""A faithful reproduction of the paper's hypothesis method, for side-by-side measurement.

Tsai & Sundaresan, "Find Me", single-image step 2: Hough line segments, collinear ones
merged into long lines; vertical lines and lines above the horizon dropped, with the camera
assumed level (optical axis parallel to the floor: the horizon is the row through the
principal point, whatever the phone's tilt); the rest clustered by image slope into left /
front / right; a hypothesis is a polyline from the left to the right border made of at most
one line from each group, in the order left, front, right, consecutive lines joined at their
intersection; its score is the fraction of its length lying on edge pixels (Canny), and
hypotheses below ``min_support`` are dropped.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from findme_core.geometry.camera import Camera
from findme_core.single.hypotheses import Hypothesis, HypothesisSet, _check_image, _timing
from findme_core.single.lines import LineKind, classify, detect_segments, merge_collinear
from findme_core.single.search import SegKind
from findme_core.single.support import CannyField, tabulate


@dataclass(frozen=True)
class PaperParams:
    min_segment_px: float = 20.0
    min_support: float = 0.3
    vertical_tol_deg: float = 10.0
    front_slope_deg: float = 10.0


def _combos(groups):
    """Index tuples with at most one line per group, groups in order left, front, right."""
    L, F, R = groups
    out = [(i,) for g in groups for i in g]
    for a, b in ((L, F), (F, R), (L, R)):
        out += [(i, j) for i in a for j in b]
    out += [(i, j, k) for i in L for j in F for k in R]
    return out


def generate(image: np.ndarray, camera: Camera, max_n: int = 10,
             params: PaperParams = PaperParams(), clock=None) -> HypothesisSet:
    """The paper's hypotheses for one photo, best (highest edge support) first."""
    _check_image(image, camera)
    H, W = image.shape[:2]
    level = camera.with_gravity(None)  # the paper's level-camera assumption
    t = [clock()] if clock else []
    lines = merge_collinear(detect_segments(image, "hough", params.min_segment_px))
    kinds = classify(lines, level, vertical_tol_deg=params.vertical_tol_deg, horizon_margin=0.0,
                     front_slope_deg=params.front_slope_deg)
    idx = [np.nonzero((kinds == k) & (np.abs(lines.coef[:, 1]) > 0.05))[0][:15]
           for k in (LineKind.LEFT, LineKind.FRONT, LineKind.RIGHT)]
    if clock:
        t.append(clock())
    cand = np.concatenate(idx)
    local = {int(g): i for i, g in enumerate(cand)}
    idx = [[local[int(g)] for g in grp] for grp in idx]
    coef = lines.coef[cand]
    if len(cand) == 0:
        return HypothesisSet(W, H, [], lines, kinds, "no line below the horizon",
                             _timing(t, ("lines",)))
    table = tabulate(CannyField(image), coef)
    hyps = []
    for combo in _combos(idx):
        poly = _polyline(coef, combo, W)
        if poly is None:
            continue
        ks = [int(np.clip(round(u + 0.5), 0, W)) for u in poly[:, 0]]
        ks[0], ks[-1] = 0, W
        sup = sum(table.S[i, b] - table.S[i, a] for i, a, b in zip(combo, ks[:-1], ks[1:]))
        ln = sum(table.L[i, b] - table.L[i, a] for i, a, b in zip(combo, ks[:-1], ks[1:]))
        frac = sup / ln if ln > 0 else 0.0
        if frac >= params.min_support:
            hyps.append(Hypothesis(poly, np.full(len(poly) - 1, SegKind.WALL), frac, frac))
    hyps.sort(key=lambda h: -h.score)
    if clock:
        t.append(clock())
    reason = None if hyps else "no hypothesis reaches the edge-support threshold"
    return HypothesisSet(W, H, hyps[:max_n], lines, kinds, reason,
                         _timing(t, ("lines", "hypotheses")))


def _polyline(coef, combo, W):
    """Border, corners, border; None unless the corners run left to right inside the image."""
    def row(c, u):
        return -(c[0] * u + c[2]) / c[1]

    pts = [(0.0, row(coef[combo[0]], 0.0))]
    for a, b in zip(combo[:-1], combo[1:]):
        x = np.cross(coef[a], coef[b])
        if abs(x[2]) < 1e-12:
            return None
        u = x[0] / x[2]
        if not (pts[-1][0] < u < W - 1):
            return None
        pts.append((u, x[1] / x[2]))
    pts.append((W - 1.0, row(coef[combo[-1]], W - 1.0)))
    return np.array(pts)
