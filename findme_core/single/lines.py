"""Lines: merging of collinear segments (``segments`` detects them) and classification in
the level frame (vertical / above the horizon / floor line grouped left, front, right).

Segments and lines are (N, 4) float arrays ``[u1, v1, u2, v2]`` in pixels (pixel-centre
origin). A merged line also carries its homogeneous image line ``(a, b, c)`` with
``a^2 + b^2 = 1`` so that ``a u + b v + c`` is the signed distance in pixels.
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import IntEnum

import numpy as np

from findme_core.geometry.camera import Camera
from findme_core.single.support import sample_bilinear
# detection lives in ``segments``; re-exported here, where it was first defined
from findme_core.single.segments import (SEGMENT_METHODS, detect_segments,  # noqa: F401
                                         horizon_top_row)


class LineKind(IntEnum):
    """Classification of a merged line. LEFT/FRONT/RIGHT are floor-line groups (paper step 2):
    a LEFT line rises towards the image centre from the left (receding wall on the left),
    RIGHT the mirror image, FRONT runs across the view."""

    VERTICAL = 0
    ABOVE_HORIZON = 1
    LEFT = 2
    FRONT = 3
    RIGHT = 4


@dataclass(frozen=True)
class Lines:
    """Merged lines of one image.

    Attributes:
        ends: (N, 4) extent of the supporting segments ``[u1, v1, u2, v2]``, u1 <= u2.
        coef: (N, 3) homogeneous line (a, b, c), a^2 + b^2 = 1, b >= 0 (normal points down).
        support: (N,) total length in pixels of the segments merged into the line.
    """

    ends: np.ndarray
    coef: np.ndarray
    support: np.ndarray

    def __len__(self) -> int:
        return len(self.ends)

    def subset(self, mask) -> "Lines":
        return Lines(self.ends[mask], self.coef[mask], self.support[mask])

    @property
    def length(self) -> np.ndarray:
        """(N,) extent length in pixels."""
        d = self.ends[:, 2:] - self.ends[:, :2]
        return np.hypot(d[:, 0], d[:, 1])


def _fit_lines(pts: np.ndarray, w: np.ndarray, group: np.ndarray, n: int) -> np.ndarray:
    """Weighted total-least-squares lines of ``n`` point groups (closed form, 2x2 scatter).

    Args:
        pts: (M, 2) points; w: (M,) weights; group: (M,) group index in [0, n).
    Returns:
        (n, 3) lines (a, b, c), a^2 + b^2 = 1, b >= 0.

    A group whose weights are all zero (e.g. segments of zero length) is fitted with equal
    weights instead of dividing by zero.
    """
    w = np.where(np.bincount(group, w, n)[group] > 0, w, 1.0)
    sw = np.bincount(group, w, n)
    mx = np.bincount(group, w * pts[:, 0], n) / sw
    my = np.bincount(group, w * pts[:, 1], n) / sw
    dx, dy = pts[:, 0] - mx[group], pts[:, 1] - my[group]
    sxx = np.bincount(group, w * dx * dx, n)
    syy = np.bincount(group, w * dy * dy, n)
    sxy = np.bincount(group, w * dx * dy, n)
    theta = 0.5 * np.arctan2(2 * sxy, sxx - syy)   # direction of largest spread
    a, b = -np.sin(theta), np.cos(theta)            # normal
    flip = (b < 0) | ((b == 0) & (a < 0))
    a, b = np.where(flip, -a, a), np.where(flip, -b, b)
    return np.column_stack([a, b, -(a * mx + b * my)])


def _group_collinear(p1, p2, weight, angle_tol_deg, dist_tol_px):
    """Greedy grouping, heaviest first: (N,) group index of each segment."""
    n = len(p1)
    d = p2 - p1
    ln = np.maximum(np.hypot(d[:, 0], d[:, 1]), 1e-9)
    dirs = d / ln[:, None]
    nrm = np.column_stack([-dirs[:, 1], dirs[:, 0]])
    c = -(nrm * p1).sum(1)
    # 2-D products summed in a fixed order (no BLAS): which segments group is then the same
    # under every BLAS kernel
    dot2 = lambda a, b: a[:, None, 0] * b[None, :, 0] + a[:, None, 1] * b[None, :, 1]  # noqa: E731
    cos_ok = np.abs(dot2(dirs, dirs)) >= np.cos(np.radians(angle_tol_deg))
    # distance of segment j's endpoints to the line of segment i
    d1 = np.abs(dot2(nrm, p1) + c[:, None])
    d2 = np.abs(dot2(nrm, p2) + c[:, None])
    compat = cos_ok & (np.maximum(d1, d2) <= dist_tol_px)
    if n == 0:
        return np.zeros(0, int), 0
    # the greedy pass on bit sets (Python ints, bit j of row i = compat[i, j]): a group is
    # its seed's compatible segments not yet in a group, and the seed
    nb = (n + 7) // 8
    packed = np.packbits(compat, axis=1, bitorder="little").tobytes()
    rows = [int.from_bytes(packed[i * nb:(i + 1) * nb], "little") for i in range(n)]
    free = (1 << n) - 1
    sets = []
    for i in np.argsort(-weight, kind="stable").tolist():
        if free >> i & 1:
            members = (rows[i] & free) | (1 << i)
            free &= ~members
            sets.append(members)
    bits = np.frombuffer(b"".join(m.to_bytes(nb, "little") for m in sets), np.uint8)
    member = np.unpackbits(bits.reshape(len(sets), nb), axis=1, count=n, bitorder="little")
    return np.argmax(member, axis=0), len(sets)   # each segment is in one group


def merge_collinear(segments: np.ndarray, angle_tol_deg: float = 2.0,
                    dist_tol_px: float = 1.5, weights: np.ndarray | None = None) -> Lines:
    """Merge collinear segments into long lines (paper step 2).

    Heaviest (longest) segment first, every unassigned segment within ``angle_tol_deg`` whose
    both endpoints lie within ``dist_tol_px`` of the seed's line joins it; each group is
    refitted (total least squares on endpoints and midpoints, weighted by length), and the
    merged lines are merged once more the same way. Gaps are allowed: hypotheses use each
    line as an infinite line.

    Args:
        segments: (N, 4) ``[u1, v1, u2, v2]``.
        weights: (N,) support of each segment (default its length).
    Returns:
        Lines with M <= N entries, heaviest support first.
    """
    segs = np.asarray(segments, dtype=float).reshape(-1, 4)
    if len(segs) == 0:
        return Lines(np.zeros((0, 4)), np.zeros((0, 3)), np.zeros(0))
    d = segs[:, 2:] - segs[:, :2]
    sup = np.hypot(d[:, 0], d[:, 1]) if weights is None else np.asarray(weights, float)
    for _ in range(2):
        p1, p2 = segs[:, :2], segs[:, 2:]
        group, n = _group_collinear(p1, p2, sup, angle_tol_deg, dist_tol_px)
        ln = np.hypot(*(p2 - p1).T)
        pts = np.concatenate([p1, p2, (p1 + p2) / 2])
        coef = _fit_lines(pts, np.tile(np.maximum(ln, 1e-3), 3), np.tile(group, 3), n)
        # extent: project members' endpoints on their line
        dirn = np.column_stack([coef[:, 1], -coef[:, 0]])
        dirn = np.where(dirn[:, :1] < 0, -dirn, dirn)
        foot = -coef[:, 2:3] * coef[:, :2]
        t = np.concatenate([((p1 - foot[group]) * dirn[group]).sum(1),
                            ((p2 - foot[group]) * dirn[group]).sum(1)])
        gg = np.tile(group, 2)
        tmin = np.full(n, np.inf)
        tmax = np.full(n, -np.inf)
        np.minimum.at(tmin, gg, t)
        np.maximum.at(tmax, gg, t)
        a, b = foot + tmin[:, None] * dirn, foot + tmax[:, None] * dirn
        segs = np.column_stack([a, b])
        sup = np.bincount(group, sup, n)
    o = np.argsort(-sup, kind="stable")
    return Lines(segs[o], coef[o], sup[o])


def snap_to_edges(gray: np.ndarray, lines: Lines, step_px: float = 2.0,
                  reach_px: int = 2, straight_px: float = 1.0) -> Lines:
    """The lines refitted to the sub-pixel edge positions of the image along them.

    Every ``step_px`` along a line the image is sampled across it at -reach..reach pixels;
    the strongest central difference of the line's own polarity there, refined by a
    parabola, is the edge's position. A line is refitted (weighted total least squares,
    weights = edge strength) to its positions where the edge is at least half its mean
    strength, then once more without the positions farther than ``trim_px`` from that fit
    (a line merged from two nearly collinear edges keeps the one it mostly lies on). Lines
    detected at a reduced scale (LSD's ``lsd_scale``) so regain full-resolution angles.

    Args:
        gray: (H, W) float32 grey image.
        lines: (N) lines in its pixels.
    Returns:
        Lines with refitted ``coef`` and ``ends``, and ``support`` scaled by the fraction of
        the line's positions the final fit kept; a line with fewer than 6 usable positions
        keeps its old line.
    """
    n = len(lines)
    if n == 0:
        return lines
    a, b = lines.ends[:, :2], lines.ends[:, 2:]
    length = lines.length
    k = np.maximum((length / step_px).astype(int), 1)
    idx = np.repeat(np.arange(n), k)
    t = (np.arange(k.sum()) - np.repeat(np.cumsum(k) - k, k) + 0.5) / k[idx]
    pts = a[idx] + t[:, None] * (b[idx] - a[idx])                       # (P, 2)
    nrm = lines.coef[idx, :2]
    off = np.arange(-reach_px - 1, reach_px + 2, dtype=float)          # one more each side
    prof = sample_bilinear(gray, (pts[:, None, :] + off[None, :, None] * nrm[:, None, :])
                           .astype(np.float32))
    d = prof[:, 2:] - prof[:, :-2]                                      # at -reach..reach
    # the edge's polarity: the sign of the line's mean difference at its own position (a
    # neighbouring edge of the other polarity, a baseboard's other side, is not taken)
    sign = np.sign(np.bincount(idx, d[:, reach_px], n))[idx]
    g = np.maximum(d * sign[:, None], 0.0)
    j = np.clip(np.argmax(g, axis=1), 1, g.shape[1] - 2)
    r = np.arange(len(g))
    g0, g1, g2 = g[r, j - 1], g[r, j], g[r, j + 1]
    den = g0 - 2 * g1 + g2
    frac = np.where(den < -1e-6, 0.5 * (g0 - g2) / np.where(den < -1e-6, den, -1.0), 0.0)
    pos = pts + ((j - reach_px) + np.clip(frac, -0.5, 0.5))[:, None] * nrm
    mean = np.bincount(idx, g1, n) / k
    good = g1 >= 0.5 * mean[idx]
    cnt = np.bincount(idx[good], minlength=n)
    wgt = g1[good].astype(float)
    coef = np.where((cnt >= 6)[:, None], _fit_lines(pos[good], wgt, idx[good], np.maximum(n, 1))
                    if good.any() else lines.coef, lines.coef)
    # how straight the edge is: a line merged from two nearly collinear edges, or an edge
    # that bends, is trusted less (support scaled by 1 / (1 + (rms / straight_px)^2))
    d2 = ((coef[idx[good], :2] * pos[good]).sum(1) + coef[idx[good], 2]) ** 2
    rms = np.sqrt(np.bincount(idx[good], wgt * d2, n) / np.maximum(np.bincount(idx[good], wgt, n), 1e-12))
    trust = np.where(cnt >= 6, 1.0 / (1.0 + (rms / straight_px) ** 2), 1.0)
    # extents: the old ends projected on the new lines
    foot = lambda p, c: p - (c[:, :2] * p).sum(1, keepdims=True) * c[:, :2] - c[:, 2:] * c[:, :2]  # noqa: E731
    ends = np.column_stack([foot(a, coef), foot(b, coef)])
    return Lines(ends, coef, lines.support * trust)


def vertical_angle_deg(lines: Lines, camera: Camera) -> np.ndarray:
    """(N,) angle in degrees between each line and the image direction of 3D vertical lines
    at the line's midpoint (0 = the line is the image of a vertical 3D line)."""
    if len(lines) == 0:
        return np.zeros(0)
    mid = (lines.ends[:, :2] + lines.ends[:, 2:]) / 2
    up = camera.up_direction(mid)
    dirn = np.column_stack([lines.coef[:, 1], -lines.coef[:, 0]])
    c = np.abs((up * dirn).sum(1))
    return np.degrees(np.arccos(np.clip(c, 0.0, 1.0)))


def classify(lines: Lines, camera: Camera, vertical_tol_deg: float = 8.0,
             horizon_margin: float = 0.02, front_slope_deg: float = 10.0) -> np.ndarray:
    """Classify each line (paper step 2, generalised to a tilted camera by gravity).

    A line is VERTICAL if it points at the vertical vanishing point within
    ``vertical_tol_deg``; ABOVE_HORIZON if an endpoint's ray does not point down by more than
    ``horizon_margin`` (ray y / |ray| in the level frame; the image of a floor line lies
    strictly below the horizon). The rest are floor-line candidates grouped by their slope in
    the level-rectified image (rays divided by their level z): FRONT if within
    ``front_slope_deg`` of horizontal, LEFT if rising to the right, RIGHT if falling.

    Returns:
        (N,) int array of LineKind values.
    """
    n = len(lines)
    kinds = np.full(n, LineKind.FRONT, dtype=int)
    if n == 0:
        return kinds
    vert = vertical_angle_deg(lines, camera) < vertical_tol_deg
    below = (camera.below_horizon(lines.ends[:, :2], horizon_margin)
             & camera.below_horizon(lines.ends[:, 2:], horizon_margin))
    r1, r2 = camera.rays_level(lines.ends[:, :2]), camera.rays_level(lines.ends[:, 2:])
    # level-rectified image coordinates (x/z, y/z); both ends are below the horizon here
    z1, z2 = np.where(np.abs(r1[:, 2]) > 1e-9, r1[:, 2], 1e-9), np.where(np.abs(r2[:, 2]) > 1e-9, r2[:, 2], 1e-9)
    du = r2[:, 0] / z2 - r1[:, 0] / z1
    dv = r2[:, 1] / z2 - r1[:, 1] / z1
    flip = du < 0
    du, dv = np.where(flip, -du, du), np.where(flip, -dv, dv)
    slope = np.degrees(np.arctan2(dv, du))  # > 0: falling to the right (image v grows down)
    kinds[slope < -front_slope_deg] = LineKind.LEFT
    kinds[slope > front_slope_deg] = LineKind.RIGHT
    kinds[~below] = LineKind.ABOVE_HORIZON
    kinds[vert] = LineKind.VERTICAL
    return kinds
