"""Vertical wall corners: the straight edge rising from a floor corner, found in the image
where the line detector misses it.

Two walls of one paint meet in a corner whose edge is only a bend of the shading, a grey
level or two deep: far too faint for LSD, while the two floor lines (baseboards) meeting
below it are strong. A photo showing only such a corner and its baseboards gives too few
lines for its vanishing directions; the corner's vertical edge is what tells the tilt. So:
every L-junction of two strong lines (their intersection near an end of both, at an angle)
is a floor-corner candidate, and rays rising from it at -``max_deg``..``max_deg`` from the
image's up direction are scored by the mean crease across them (it keeps its sign along the
corner while texture averages out); the best ray, when clearly above the others, is the
corner's edge.

Pixels (u, v), pixel-centre origin; angles in radians unless named ``_deg``.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from findme_core.single.support import sample_bilinear


@dataclass(frozen=True)
class CornerParams:
    max_corners: int = 6          # candidate floor corners examined (heaviest lines first)
    pair_lines: int = 24          # corners from pairs of the heaviest lines
    min_angle_deg: float = 20.0   # the two lines of a corner differ by at least this
    reach_px: float = 12.0        # the corner lies within this (+ 10 % of the length) of
                                  # an end of both lines
    max_deg: float = 45.0         # rays searched from the image's up direction, degrees
    step_deg: float = 1.0
    exclude_deg: float = 10.0     # rays near a corner line's own direction are not searched
    through_px: float = 4.0       # a line passing this near the corner is one of its own
    r0_px: float = 6.0            # rays start this far from the corner
    max_len_px: float = 150.0
    min_len_px: float = 40.0
    sample_px: float = 4.0        # spacing of the samples along a ray
    offset_px: float = 4.0        # the crease is taken +- this across the ray
    blur_sigma: float = 1.5
    min_t: float = 6.0            # t statistic (mean / standard error) of a corner edge
    prominence: float = 3.0       # best ray's t / median t over all rays


def floor_corners(ends: np.ndarray, weight: np.ndarray, width: int, height: int,
                  p: CornerParams = CornerParams()) -> tuple[np.ndarray, np.ndarray]:
    """L-junctions of lines: ((K, 2) corner pixels, (K, 2) indices of their two lines),
    heaviest pair first (by the lighter line's weight), at most ``p.max_corners``, none
    within 6 px of a heavier one.

    Args:
        ends: (N, 4) line extents ``[u1, v1, u2, v2]``; weight: (N,) their support.
    """
    n = min(len(ends), p.pair_lines)
    if n < 2:
        return np.zeros((0, 2)), np.zeros((0, 2), int)
    a, b = ends[:n, :2], ends[:n, 2:]
    d = b - a
    ln = np.maximum(np.hypot(d[:, 0], d[:, 1]), 1e-9)
    t = d / ln[:, None]
    i, j = np.triu_indices(n, 1)
    cross = t[i, 0] * t[j, 1] - t[i, 1] * t[j, 0]
    ok = np.abs(cross) >= np.sin(np.radians(p.min_angle_deg))
    i, j, cross = i[ok], j[ok], cross[ok]
    # a[i] + s t[i] = a[j] + r t[j]
    w = a[j] - a[i]
    s = (w[:, 0] * t[j, 1] - w[:, 1] * t[j, 0]) / cross
    r = (w[:, 0] * t[i, 1] - w[:, 1] * t[i, 0]) / cross
    X = a[i] + s[:, None] * t[i]

    def near_end(k, par):   # beyond or near an end of line k, not across its middle
        slack = p.reach_px + 0.1 * ln[k]
        return ((par >= -slack) & (par <= slack)) | ((par >= ln[k] - slack) & (par <= ln[k] + slack))

    ok = (near_end(i, s) & near_end(j, r) & (X[:, 0] >= 0) & (X[:, 0] <= width - 1)
          & (X[:, 1] >= 0) & (X[:, 1] <= height - 1))
    i, j, X = i[ok], j[ok], X[ok]
    order = np.argsort(-np.minimum(weight[i], weight[j]), kind="stable")
    corners, pairs = [], []
    for k in order:
        if all(np.hypot(*(X[k] - c)) > 6.0 for c in corners):
            corners.append(X[k])
            pairs.append((i[k], j[k]))
            if len(corners) == p.max_corners:
                break
    return np.array(corners).reshape(-1, 2), np.array(pairs, int).reshape(-1, 2)


def corner_verticals(gray: np.ndarray, ends: np.ndarray, weight: np.ndarray,
                     p: CornerParams = CornerParams()) -> tuple[np.ndarray, np.ndarray]:
    """The straight edges rising from the floor corners of ``ends``.

    Along each ray from a corner the blurred image is sampled at +-``offset_px`` across it
    and on it (a, b, m): the mean crease a + b - 2 m (the shading of two walls meeting at an
    angle bends there; a plain step of brightness, which shadows and pictures make too, is
    not asked for) is compared with its standard error along the ray (a t statistic). The
    best ray of a corner is kept when its t is at least ``min_t`` and ``prominence`` times
    the median over all rays; its angle is refined by a parabola through the neighbouring
    rays' t.

    Args:
        gray: (H, W) uint8 or float32 grey image.
        ends: (N, 4) merged line extents, heaviest first; weight: (N,) their support.
    Returns:
        ((K, 4) segments from each corner along its edge, (K,) their t statistics).
    """
    H, W = gray.shape
    corners, pairs = floor_corners(ends, weight, W, H, p)
    if not len(corners):
        return np.zeros((0, 4)), np.zeros(0)
    d = ends[:, 2:] - ends[:, :2]
    nrm = np.column_stack([-d[:, 1], d[:, 0]]) / np.maximum(np.hypot(d[:, 0], d[:, 1]), 1e-9)[:, None]
    coef = np.column_stack([nrm, -(nrm * ends[:, :2]).sum(1)])
    img = cv2.GaussianBlur(gray.astype(np.float32), (0, 0), p.blur_sigma)
    th = np.radians(np.arange(-p.max_deg, p.max_deg + 1e-9, p.step_deg))
    U = np.column_stack([np.sin(th), -np.cos(th)])                        # (T, 2) up-ish
    Nn = np.column_stack([np.cos(th), np.sin(th)])
    r = np.arange(p.r0_px, p.max_len_px, p.sample_px)
    segs, ts = [], []
    for c, (i, j) in zip(corners, pairs):
        with np.errstate(divide="ignore"):   # usable length of each ray inside the image
            lim_u = np.where(U[:, 0] > 1e-9, (W - 1 - c[0]) / U[:, 0],
                             np.where(U[:, 0] < -1e-9, -c[0] / U[:, 0], np.inf))
            lim_v = np.where(U[:, 1] < -1e-9, -c[1] / U[:, 1], np.inf)
        lim = np.minimum(np.minimum(lim_u, lim_v), p.max_len_px)
        ok = lim >= p.min_len_px
        # not along a line through the corner (its own two, or another that LSD found:
        # that edge needs no finding); their extension beyond the corner is searched
        through = np.abs(coef[:, :2] @ c + coef[:, 2]) < p.through_px
        for k in np.flatnonzero(through | (np.arange(len(ends)) == i) | (np.arange(len(ends)) == j)):
            t = (ends[k, :2] + ends[k, 2:]) / 2 - c
            t = t / max(np.hypot(*t), 1e-9)
            ok &= U @ t < np.cos(np.radians(p.exclude_deg))
        if ok.sum() < 5:
            continue
        base = c + r[None, :, None] * U[:, None, :]                       # (T, R, 2)
        off = p.offset_px * Nn[:, None, :]
        a, b, m = (sample_bilinear(img, base + off), sample_bilinear(img, base - off),
                   sample_bilinear(img, base))
        valid = r[None, :] <= lim[:, None]
        n = np.maximum(valid.sum(1), 2)
        d = a + b - 2 * m                                                  # crease
        mean = np.where(valid, d, 0.0).sum(1) / n
        var = np.where(valid, (d - mean[:, None]) ** 2, 0.0).sum(1) / (n - 1)
        best = np.where(ok, np.abs(mean) / np.sqrt(var / n + 1e-4), 0.0)
        k = int(np.argmax(best))
        if best[k] < p.min_t or best[k] < p.prominence * np.median(best[ok]):
            continue
        dk = 0.0
        if 0 < k < len(th) - 1 and ok[k - 1] and ok[k + 1]:
            den = best[k - 1] - 2 * best[k] + best[k + 1]
            if den < 0:
                dk = float(np.clip(0.5 * (best[k - 1] - best[k + 1]) / den, -0.5, 0.5))
        ang = th[k] + dk * np.radians(p.step_deg)
        u = np.array([np.sin(ang), -np.cos(ang)])
        segs.append(np.concatenate([c, c + float(lim[k]) * u]))
        ts.append(float(best[k]))
    return np.array(segs).reshape(-1, 4), np.array(ts)
