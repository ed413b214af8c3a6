"""Line segments: detection, merging of collinear segments, and classification in the
level frame (vertical / above the horizon / floor line grouped left, front, right).

Segments and lines are (N, 4) float arrays ``[u1, v1, u2, v2]`` in pixels (pixel-centre
origin). A merged line also carries its homogeneous image line ``(a, b, c)`` with
``a^2 + b^2 = 1`` so that ``a u + b v + c`` is the signed distance in pixels.
"""

from __future__ import annotations

import threading
from dataclasses import dataclass
from enum import IntEnum

import cv2
import numpy as np

from .camera import Camera
from .errors import InputError

SEGMENT_METHODS = ("lsd", "hough")


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


def _gray(image: np.ndarray) -> np.ndarray:
    if image.ndim == 3:
        return cv2.cvtColor(image, cv2.COLOR_BGR2GRAY)
    if image.ndim != 2:
        raise InputError(f"image must be HxW or HxWx3, got shape {image.shape}")
    return image


_LOCAL = threading.local()  # one LSD per thread and scale: detect() is not re-entrant


def _lsd(scale: float):
    cache = _LOCAL.__dict__.setdefault("lsd", {})
    if scale not in cache:
        cache[scale] = cv2.createLineSegmentDetector(cv2.LSD_REFINE_STD, scale)
    return cache[scale]


def horizon_top_row(camera: Camera, margin_px: float = 8.0) -> int:
    """First image row (even, >= 0) at or below which every floor line of ``camera`` lies:
    ``margin_px`` above the highest point of the horizon in the image; 0 when the horizon
    does not run across the image with the floor below it (the whole image is searched)."""
    a, b, c = camera.horizon_line()
    if b <= 1e-12 or abs(a) > 4 * b:  # floor not below the horizon, or horizon too steep
        return 0
    top = min(-(c + a * u) / b for u in (0.0, camera.width - 1.0)) - margin_px
    return int(np.clip(np.floor(top / 2) * 2, 0, max(camera.height - 2, 0)))


def detect_segments(image: np.ndarray, method: str = "lsd", min_length: float = 12.0,
                    lsd_scale: float = 0.8, border_px: float = 2.5,
                    top_row: int = 0) -> np.ndarray:
    """Detect straight segments.

    Args:
        image: (H, W) or (H, W, 3) uint8 (BGR).
        method: ``"lsd"`` (OpenCV LSD, sub-pixel) or ``"hough"`` (Canny + HoughLinesP, as the
            paper).
        min_length: drop segments shorter than this, pixels.
        lsd_scale: LSD's internal down-scaling (0.8 is LSD's default; smaller is faster).
        border_px: segments lying within this distance of one image border are the frame's
            own edge (dark borders), not scene lines, and are dropped.
        top_row: detect in rows >= ``top_row`` only (e.g. ``horizon_top_row``: the rows
            below the horizon, where floor lines are); an even row keeps LSD's sampling grid.
    Returns:
        (N, 4) float64 ``[u1, v1, u2, v2]`` in the pixels of the whole image.
    """
    gray = _gray(image)
    h, w = gray.shape
    top = int(np.clip(top_row, 0, max(h - 1, 0)))
    if method == "lsd":
        segs = _lsd(float(lsd_scale)).detect(gray[top:] if top else gray)[0]
        if segs is not None and top:
            segs = segs.reshape(-1, 4) + np.array([0, top, 0, top], np.float32)
    elif method == "hough":
        edges = cv2.Canny(gray[top:] if top else gray, 50, 150)
        segs = cv2.HoughLinesP(edges, 1, np.pi / 180, 40, minLineLength=int(min_length) + 8,
                               maxLineGap=4)
        if segs is not None:  # Canny marks the pixel before a step: shift to the step itself
            segs = segs.reshape(-1, 4).astype(float) + np.array([0.5, 0.5 + top, 0.5, 0.5 + top])
    else:
        raise InputError(f"unknown segment method {method!r}; choose one of {SEGMENT_METHODS}")
    if segs is None or len(segs) == 0:
        return np.zeros((0, 4))
    segs = np.asarray(segs, dtype=float).reshape(-1, 4)
    d = segs[:, 2:] - segs[:, :2]
    keep = np.hypot(d[:, 0], d[:, 1]) >= min_length
    # edges of the image frame itself (dark borders left by rectification or registration)
    u, v = segs[:, [0, 2]], segs[:, [1, 3]]
    m = border_px
    frame = ((u <= m).all(1) | (u >= w - 1 - m).all(1) | (v <= m).all(1) | (v >= h - 1 - m).all(1))
    return segs[keep & ~frame]


def _fit_lines(pts: np.ndarray, w: np.ndarray, group: np.ndarray, n: int) -> np.ndarray:
    """Weighted total-least-squares lines of ``n`` point groups (closed form, 2x2 scatter).

    Args:
        pts: (M, 2) points; w: (M,) weights; group: (M,) group index in [0, n).
    Returns:
        (n, 3) lines (a, b, c), a^2 + b^2 = 1, b >= 0.
    """
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
    cos_ok = np.abs(dirs @ dirs.T) >= np.cos(np.radians(angle_tol_deg))
    # distance of segment j's endpoints to the line of segment i
    d1 = np.abs(nrm @ p1.T + c[:, None])
    d2 = np.abs(nrm @ p2.T + c[:, None])
    compat = cos_ok & (np.maximum(d1, d2) <= dist_tol_px)
    group = np.full(n, -1)
    g = 0
    for i in np.argsort(-weight, kind="stable"):
        if group[i] >= 0:
            continue
        members = compat[i] & (group < 0)
        members[i] = True
        group[members] = g
        g += 1
    return group, g


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
