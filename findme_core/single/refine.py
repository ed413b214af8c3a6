"""Snap a boundary to the wall base when a baseboard band lies between it and the floor.

Line detectors find the crisp top edge of a baseboard (wall paint against wood) and often
miss its soft bottom edge against the floor, which is the real ground-wall boundary: a
wall point computed from the top edge is ~10 % too far. A baseboard is a band of the wall
of fixed height; in the image its width is a fixed fraction of the boundary's depression
below the horizon (a level camera sees height y above the floor at (h - y) / h of the
floor's depression). So we average the colour profile across each WALL segment in
*relative* offsets s = offset / depression, over the whole segment (a strong average where
one column is noise), find where the profile settles into the floor colour, and move the
segment's line down to the last colour edge before it. A floor of planks or tiles along the
wall may never settle within the search: a band of one colour just below the line, unlike
the floor and ending at a colour edge, is taken first (``_band_end``: a baseboard). A band
with the floor's chromaticity but darker is a shadow on the floor (under furniture) and is
left alone.
"""

from __future__ import annotations

from dataclasses import dataclass

import math

import numpy as np

from findme_core.geometry.camera import Camera
from findme_core.single.search import SegKind
from findme_core.single.support import sample_bilinear_xy


@dataclass(frozen=True)
class SnapParams:
    max_rel: float = 0.16        # deepest band searched, relative to the depression
    floor_band: tuple[float, float] = (0.2, 0.3)  # where the floor colour is sampled
    settle_tol: float = 12.0     # Lab distance counted as "floor colour"
    settle_len: float = 0.04     # the profile must stay at the floor colour this long
    min_shift_px: float = 1.5
    shadow_chroma: float = 6.0   # a band with the floor's chroma (a, b) and lower L is a shadow
    step_px: float = 3.0         # spacing of profile columns along the segment
    s_step: float = 0.01         # profile resolution, relative to the depression
    robust: bool = True          # median over columns (else mean)
    band_tol: float = 6.0        # Lab step between samples inside a uniform (baseboard) band


def _depression(horizon: np.ndarray, pts: np.ndarray) -> np.ndarray:
    """(M,) pixel distance from each point to the horizon (``Camera.horizon_line``, (3,)),
    measured along the image direction 'down' (towards the floor)."""
    n = np.hypot(horizon[0], horizon[1])
    return (pts @ horizon[:2] + horizon[2]) / max(n, 1e-12)


def _down(camera: Camera) -> np.ndarray:
    """(2,) unit image direction away from the horizon (towards the floor)."""
    l = camera.horizon_line()
    return l[:2] / max(np.hypot(l[0], l[1]), 1e-12)


def snap_polyline(image_lab: np.ndarray, camera: Camera, polyline: np.ndarray,
                  kinds: np.ndarray, p: SnapParams = SnapParams(),
                  cache: dict | None = None, keys=None) -> np.ndarray:
    """Return a copy of ``polyline`` with WALL segments moved down to the wall base.

    Args:
        image_lab: (H, W, 3) Lab image (``appearance.to_lab``: uint8; float32 works too).
        polyline: (M, 2) vertices; kinds: (M - 1,) SegKind.
        cache: optional dict reused across the hypotheses of one image: key -> shift, and
            ``_short(key, a, b)`` -> None for a segment (a, b) measured too short to tell
            (the same segment of another hypothesis is then not measured again).
        keys: optional cache key per segment, e.g. the id of the image line it lies on: the
            band under a line is a property of the line, so each line is measured once
            (default: the segment's rounded end points).
    """
    poly = np.array(polyline, float)
    H, W = image_lab.shape[:2]
    down = _down(camera)
    dx, dy = float(down[0]), float(down[1])
    P = poly.tolist()   # the arithmetic below on Python floats: the same IEEE operations as
    lines = {}          # on numpy scalars, without their overhead
    wall = int(SegKind.WALL)
    for s, kind in enumerate(np.asarray(kinds).tolist()):   # Python ints: a numpy integer
        if kind != wall:                                     # against an enum is slow
            continue
        (ax, ay), (bx, by) = P[s], P[s + 1]
        key = keys[s] if keys is not None else (round(ax), round(ay), round(bx), round(by))
        short = _short(key, P[s], P[s + 1])
        if cache is not None and (key in cache or short in cache):
            shift = cache[key] if key in cache else None
        else:
            shift = segment_shifts(image_lab, camera, [(poly[s], poly[s + 1])], down, p)[0]
            if cache is not None:
                cache[key if shift is not None else short] = shift
        if shift is None:  # too short to measure: its corners follow the neighbours
            continue
        ux, uy = bx - ax, by - ay
        norm = max(math.hypot(ux, uy), 1e-12)
        nx, ny = -uy / norm, ux / norm
        if nx * dx + ny * dy < 0:
            nx, ny = -nx, -ny
        lines[s] = ((ax + shift * nx, ay + shift * ny), (ux, uy))  # point on the moved line,
    if not lines:                                                  # direction
        return poly
    out = poly.copy()
    for k in range(len(P)):
        left, right = lines.get(k - 1), lines.get(k)
        if left and right:
            x = _intersect(*left, *right)
            lo = P[k - 1][0] if k > 0 else 0.0
            hi = P[k + 1][0] if k + 1 < len(P) else W - 1.0
            # a corner of two nearly parallel lines can slide far when they move: then keep
            # its column (the polyline must stay monotonic in u) and take the lines' mean row
            if x is not None and abs(x[0] - P[k][0]) <= 2.0 and lo <= x[0] <= hi:
                out[k] = x
            else:
                out[k, 1] = (_row_at(*left, P[k][0]) + _row_at(*right, P[k][0])) / 2
            continue
        ln = left or right
        if ln is not None:
            out[k, 1] = _row_at(*ln, P[k][0])
    return out


def prefetch(image_lab: np.ndarray, camera: Camera, polylines, p: SnapParams,
             cache: dict) -> None:
    """Fill ``cache`` (as ``snap_polyline`` fills it) with the shift of every WALL segment
    of ``polylines`` [(polyline (M, 2), kinds (M - 1,), keys (M - 1,))] not in it yet, all
    measured in one remap; a key's segment is its first one, as one by one. Then
    ``snap_polyline`` with the same cache and keys gives what it gives without this (and
    the cache holds what it would hold)."""
    down = _down(camera)
    wall = int(SegKind.WALL)
    todo: dict = {}
    for polyline, kinds, keys in polylines:
        poly = np.array(polyline, float)
        for k, kind in enumerate(np.asarray(kinds).tolist()):
            if kind == wall and keys[k] not in cache and keys[k] not in todo:
                todo[keys[k]] = (poly[k], poly[k + 1])
    for key, shift in zip(todo, segment_shifts(image_lab, camera, list(todo.values()), down, p)):
        if shift is not None:   # as snap_polyline: a segment too short to tell is not kept
            cache[key] = shift  # for its line (a longer one of the same line, later, may
        else:                   # tell), only for itself
            a, b = todo[key]
            cache[_short(key, a.tolist(), b.tolist())] = None


def _short(key, a, b) -> tuple:
    """The cache key saying that the segment a-b ([x, y] lists) of line ``key`` is too short
    to tell (no line key is a tuple starting with this string)."""
    return ("too short", key, *a, *b)


def _row_at(q, d, u):
    return q[1] + (u - q[0]) * d[1] / d[0] if abs(d[0]) > 1e-9 else q[1]


def _intersect(p, d, q, e):
    """Intersection (x, y) of the lines p + t d and q + s e (None if nearly parallel)."""
    det = e[0] * d[1] - d[0] * e[1]
    if abs(det) < 1e-9:
        return None
    t = (e[0] * (q[1] - p[1]) - e[1] * (q[0] - p[0])) / det
    return (p[0] + t * d[0], p[1] + t * d[1])


def _median0(x: np.ndarray) -> np.ndarray:
    """np.median(x, axis=0) of x without NaN, by one sort (the same order statistics, so the
    same values; numpy sorts faster than it partitions each of many short columns)."""
    n = x.shape[0]
    k = n // 2
    q = np.sort(x, axis=0)
    return q[k] if n % 2 else (q[k - 1] + q[k]) / 2


def segment_shifts(lab, camera, segments, down, p: SnapParams) -> list:
    """Pixels to move each segment (a, b) of ``segments`` along its normal, their samples
    taken in one remap.

    Args:
        lab: (H, W, 3) Lab image; segments: [((2,) a, (2,) b)] in pixels; down: (2,) unit
            image direction away from the horizon.
    Returns:
        per segment the shift in pixels (0 = keep) or None (too little of it to tell).
    """
    H, W = lab.shape[:2]
    out: list = [None] * len(segments)
    # every segment's columns at once, elementwise as one segment at a time: column i of a
    # segment with n columns lies at t = (i + 0.5) / n of it
    a = np.array([q for q, _ in segments], float).reshape(-1, 2)
    d = np.array([r for _, r in segments], float).reshape(-1, 2) - a
    n = np.array([int(math.hypot(x, y) // p.step_px) for x, y in d.tolist()], int)
    n = np.where(n < 4, 0, n)                     # too short: no columns
    if not n.any():
        return out
    seg = np.repeat(np.arange(len(n)), n)
    i = np.arange(len(seg)) - np.repeat(np.cumsum(n) - n, n)
    t = (i + 0.5) / n[seg]
    base = a[seg] + t[:, None] * d[seg]
    inside = ((base[:, 0] >= 0) & (base[:, 0] <= W - 1) & (base[:, 1] >= 0)
              & (base[:, 1] <= H - 1))
    seg, base = seg[inside], base[inside]
    ok = np.bincount(seg, minlength=len(n)) >= 4
    if not ok.any():
        return out
    seg, base = seg[ok[seg]], base[ok[seg]]
    s = _offsets(p)
    horizon = camera.horizon_line()
    bounds = np.searchsorted(seg, np.arange(len(n) + 1))
    # the depression one segment at a time: the same matrix product as before
    dep = np.concatenate([np.zeros(0)] + [_depression(horizon, base[bounds[j]:bounds[j + 1]])
                                          for j in np.nonzero(ok)[0].tolist()])
    dep = np.maximum(dep, 1.0)
    # a column of samples is a straight run: inside the image iff both its ends are (each
    # sample at base + (s * dep) * down, as before; columns and rows apart: numpy is slowest
    # on a last axis of 2)
    dx, dy = float(down[0]), float(down[1])
    e = s[[0, -1]][None, :] * dep[:, None]                                 # (M, 2)
    ex, ey = base[:, :1] + e * dx, base[:, 1:] + e * dy
    cols = ((ex >= 0) & (ex <= W - 1) & (ey >= 0) & (ey <= H - 1)).all(1)
    ok = np.bincount(seg[cols], minlength=len(n)) >= 4
    keep = cols & ok[seg]
    if not keep.any():
        return out
    seg, dep, base = seg[keep], dep[keep], base[keep]
    sd = s[None, :] * dep[:, None]                                         # (M, S)
    # every segment's samples in one remap (bilinear per sample: the same values as one
    # remap per segment; every sample lies in the image: the border mode plays no part)
    prof_all = sample_bilinear_xy((lab,), base[:, :1] + sd * dx, base[:, 1:] + sd * dy)[0]
    bounds = np.searchsorted(seg, np.arange(len(n) + 1)).tolist()
    fb = (s >= p.floor_band[0]) & (s <= p.floor_band[1])   # where the floor is sampled
    start = int(np.searchsorted(s, 0.0))                    # the line's offset
    for j in np.nonzero(ok)[0].tolist():
        lo, hi = bounds[j], bounds[j + 1]
        out[j] = _shift_from_profile(prof_all[lo:hi].astype(np.float32), s, dep[lo:hi], p,
                                     fb, start)
    return out


def _shift_from_profile(prof, s, dep, p: SnapParams, fb, start: int) -> float:
    """The shift from a segment's (n_in, S, 3) colour samples at offsets s (S,) and its
    columns' depressions dep (n_in,); fb (S,): the offsets of the floor band; the line is
    at offset index ``start``."""
    prof = _median0(prof) if p.robust else prof.mean(0)    # (S, 3) average profile
    floor = _median0(prof[fb])
    settle = _band_end(prof, s, start, floor, p)
    if settle is None:
        settle = _settling(prof, s, start, floor, p)
    if settle is None or settle == start:
        return 0.0
    # the colour edge just before settling: largest profile gradient between the top edge
    # (skipping its own blur, 2 samples) and the settling point
    grad = np.empty_like(prof)   # np.gradient(prof, axis=0)
    grad[1:-1] = (prof[2:] - prof[:-2]) / 2.0
    grad[0], grad[-1] = prof[1] - prof[0], prof[-1] - prof[-2]
    g = np.sqrt((grad * grad).sum(1))
    lo = min(start + 3, settle)
    k = lo + int(np.argmax(g[lo:settle + 1]))
    band = _median0(prof[start + 1:k + 1]) if k > start else prof[start]
    if (math.hypot(band[1] - floor[1], band[2] - floor[2]) < p.shadow_chroma
            and band[0] < floor[0]):
        return 0.0  # the floor's own colour, darker: a contact shadow on the floor, not a wall
    shift = float(s[k] * _median0(dep))
    return shift if shift >= p.min_shift_px else 0.0


def _settling(prof, s, start: int, floor, p: SnapParams) -> int | None:
    """The first offset index >= ``start`` (the line) from which the (S, 3) profile stays
    within ``settle_tol`` of the floor's colour for ``settle_len``, within ``max_rel``; None
    when it never does."""
    diff = prof - floor
    dd = diff * diff   # |diff|^2 as (dd0 + dd1) + dd2, as (diff * diff).sum(1) adds it
    far = (np.sqrt(dd[:, 0] + dd[:, 1] + dd[:, 2]) > p.settle_tol).tolist()
    win = max(1, int(round(p.settle_len / p.s_step)))
    within = (s <= p.max_rel).tolist()
    for k in range(start, len(s) - win):     # the first clean window, a dozen at most
        if within[k] and not any(far[k:k + win]):
            return k
    return None


def _band_end(prof, s, start: int, floor, p: SnapParams) -> int | None:
    """Where a uniform band just below the line ends (a baseboard), tried before the
    settling point, which a floor of planks or tiles may never reach.

    Args:
        prof: (S, 3) Lab profile at relative offsets ``s`` (S,); the line is at ``start``;
            floor: (3,) the floor's colour.
    Returns:
        the index just after the band's lower edge (used as a settling point), or None
        unless the band's samples step by less than ``band_tol``, it is at least two
        samples long, unlike the floor (> ``settle_tol``), and ends at a step of at least
        ``settle_tol`` within ``max_rel``.
    """
    step = np.sqrt(((prof[1:] - prof[:-1]) ** 2).sum(1))   # (S - 1,) sample to sample
    flat = (step < p.band_tol).tolist()   # compared as numpy compares, then Python bools
    i = start + 1
    while i < len(flat) and flat[i]:
        i += 1
    if i >= len(step) or i - start < 3 or step[i] < p.settle_tol or s[i + 1] > p.max_rel:
        return None
    band = _median0(prof[start + 1:i + 1])
    if float(np.sqrt(((band - floor) ** 2).sum())) <= p.settle_tol:
        return None
    return i + 1


def _offsets(p: SnapParams) -> np.ndarray:
    """Profile offsets s (relative to the depression), from just above the line to the
    bottom of the floor band."""
    return np.arange(-0.02, p.floor_band[1] + 1e-9, p.s_step)
