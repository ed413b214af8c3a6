"""Gravity from the image: the vertical and horizontal vanishing directions of a Manhattan
world (the paper's rooms: vertical walls meeting at right angles on a level floor).

Frames and units: pixels (u, v) with the pixel-centre origin; directions are unit 3-vectors
in the camera frame (OpenCV: x right, y down, z forward); angles in radians.

Method (``estimate_gravity``):

1. The photo's whole-frame segments at the ~640 px working size (``segments.photo_segments``:
   the very detection the hypotheses then take their below-horizon part from), merged into
   lines (``lines.merge_collinear``); a line's weight is its support (pixels of the segments
   merged into it). n = K^T l is the normal of its interpretation plane. Vertical wall
   corners too faint for the detector are looked for above floor corners (``corners``).
2. Search (``manhattan.search``): gravity hypotheses g on a grid over the tilt prior (pitch
   in ``pitch_range``, roll in ``roll_range``: an upright hand-held photo), each completed
   to a Manhattan frame, every line counting for the nearest of its three vanishing points;
   the best peaks are searched again on a finer grid.
3. The frame R = [h1, g, h2] is refined by Gauss-Newton on the signed image angles of its
   inlier lines (weights = support); the covariance sigma^2 (J^T W J)^-1 of the rotation is
   projected on gravity's two degrees of freedom (about the level x axis = pitch, z axis =
   roll) and inflated by the model error fitted on the dev split (``sigma_scale``,
   ``sigma_floor_deg``; tools/calibrate_sigma.py).
4. Too little evidence (fewer than 4 inlier lines, no vertical line and not two horizontal
   directions, a degenerate fit) or a 1-sigma above ``max_sigma_deg``: "level" is assumed,
   with ``level_sigma_deg``, and the reason is given.
5. Other refined frames whose gravity lies more than ``distinct_deg`` away and that score at
   least ``ambiguity_ratio`` of the best (one dominant family of parallel lines, such as
   floorboards, fits many frames): the photo cannot tell which, so the estimate keeps them as
   ``alternatives`` and its covariance covers them (``gravity_alternatives.widen``), with
   the reason; a session's photos of one spot decide together (``plan/shared_gravity``).

Jointly with a boundary (``floor_gravity.with_floor``): once the photo has a ground-wall
boundary, lines inside its floor region are known to lie on the floor: horizontal, but in
any direction (rugs, seams, stripes of sunlight), so they may only count as vertical; the
frame is searched again near the first estimate without their pull.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np

from findme_core.geometry import ties
from findme_core.geometry.camera import Camera
from findme_core.geometry.manhattan import LineSet, pitch_roll_deg, refine, score_frames, search
from findme_core.single import gravity_alternatives as alt
from findme_core.single.corners import CornerParams, corner_verticals
from findme_core.single.lines import merge_collinear, snap_to_edges
from findme_core.single.segments import Segments, photo_segments

DOWN = np.array([0.0, 1.0, 0.0])


@dataclass(frozen=True)
class GravityParams:
    min_line_px: float = 20.0       # lines with less support are not used
    snap: bool = True               # lines refitted to the image's edges (``snap_to_edges``)
    snap_step_px: float = 2.0
    max_lines: int = 200
    coarse_lines: int = 60          # the coarse search scores the heaviest lines only
    pitch_range: tuple = (-25.0, 60.0)   # degrees; > 0 looking down
    roll_range: tuple = (-40.0, 40.0)
    inlier_deg: float = 1.5
    coarse_deg: float = 3.0         # grid step over the prior (and inlier angle there)
    fine_deg: float = 1.0           # grid step around the best peaks
    span_deg: float = 3.0           # +- around each peak
    peaks: int = 8                  # peaks searched finely, at least ``coarse_deg`` apart
    fine_lines: int = 100           # the fine search scores the heaviest lines only
    candidates: int = 3             # best frames of the search refined, the best refined taken
    candidate_ratio: float = 0.7    # ... among those scoring this much of the best
    ambiguity_candidates: int = 6   # frames refined to look for alternatives (step 5; 0: none)
    ambiguity_ratio: float = 0.85   # an alternative scores at least this much of the best
    distinct_deg: float = 5.0       # ... and its gravity lies this far from the best's
    alternative_weight: float = 0.25  # its weight in the mixture: this x its score ratio
                                     # (tools/choose_ambiguity.py, leave one room out)
    iterations: int = 4
    min_line_sigma_deg: float = 0.5  # a unit-weight line's angle is known no better (dev:
                                     # residual scale p10 0.37, median 0.66 deg)
    corners: CornerParams | None = CornerParams()   # None: no corner search
    corner_weight: float = 0.5      # weight of a corner edge per pixel (LSD lines: 1)
    corner_below: int = 2           # corners are looked for when fewer vertical lines fit
    floor_margin_px: float = 6.0    # a line this far below a boundary lies on the floor
    floor_window_deg: float = 8.0   # the joint search stays this near the first estimate
    max_floor_vertical_px: float = 40.0  # more vertical support in the floor region: things
                                         # stand there, the boundary is not the floor's edge
    min_floor_px: float = 150.0     # less floor-line support: nothing to re-estimate
    min_gain: float = 0.02          # the joint frame must explain the rest this much better
    sigma_scale: float = 1.74       # model error: sigma = hypot(scale * sigma_fit, floor),
                                    # fitted by tools/calibrate_sigma.py on an earlier dev
                                    # run (68 % of 230 estimated gravities within 1-sigma).
                                    # Today (2026-11-30, KITTI's nominal gravity left out)
                                    # it gives 1.36: pitch and roll 0.68 / 0.99 within 1 / 3
                                    # sigma, 0.68 / 0.99 left out; 1.74 gives 0.71 / 0.99.
                                    # Kept: lowered alone it moved the fused-gravity results
                                    # both ways (ZInD level pairs' success 0.50 -> 0.41,
                                    # rooms 0.92 -> 1.00); the fusion's thresholds were
                                    # chosen with it, so they are refitted together or not
    sigma_floor_deg: float = 0.3
    max_sigma_deg: float = 4.0      # a worse estimate is not used: level assumed
    # 1-sigma (pitch, roll) of "level" when nothing better is known: how hand-held photos of
    # rooms are tilted (the dev views' true tilts, RMS about level; tools/choose_level_prior.py,
    # leave one room out 23.7-25.6 / 2.3-2.7 deg); the 10 deg used before left 27 % of the
    # dev views' pitch beyond 3 sigma
    level_sigma_deg: tuple = (24.3, 2.5)


@dataclass(frozen=True)
class GravityEstimate:
    """Gravity of one photo and how well it is known.

    Attributes:
        vector: (3,) unit gravity (down) in camera coordinates.
        cov: (2, 2) covariance of gravity's tilt, rad^2, about the level frame's x axis
            (pitch) and z axis (roll) of ``vector``.
        source: "image" (vanishing directions), "level" (assumed), or with a sensor's
            gravity (``gravity_fusion``): "input+image" (both combined) or "input" (the
            sensor's alone).
        lines: (vertical, horizontal) inlier line counts.
        reason: why "level" (or the sensor's alone) was taken, else None.
        segments: the whole-frame segments it was estimated from (for the hypotheses of
            the same photo: ``methods.hypothesize(segments=...)``), or None.
        evidence: (lines, K of the working size) it was estimated from, for ``with_floor``.
        prior: (gravity (3,), tilt covariance (2, 2)) of the sensor it was combined with.
        alternatives: ((gravity (3,), score ratio), ...) other frames the lines support
            nearly as well (step 5); ``cov`` covers them.
        fit_cov: the covariance before it was widened over the alternatives (None without).
    """

    vector: np.ndarray
    cov: np.ndarray
    source: str
    lines: tuple[int, int] = (0, 0)
    reason: str | None = None
    segments: Segments | None = field(default=None, compare=False, repr=False)
    evidence: tuple | None = field(default=None, compare=False, repr=False)
    prior: tuple | None = field(default=None, compare=False, repr=False)
    alternatives: tuple = field(default=(), compare=False, repr=False)
    fit_cov: np.ndarray | None = field(default=None, compare=False, repr=False)

    @property
    def sigma(self) -> float:
        """RMS 1-sigma of the tilt per axis, radians."""
        return float(math.sqrt(max(np.trace(self.cov), 0.0) / 2.0))


def level_estimate(reason: str, sigma_deg=GravityParams.level_sigma_deg,
                   segments: Segments | None = None) -> GravityEstimate:
    """Level (0, 1, 0) assumed, with 1-sigma ``sigma_deg``: (pitch, roll) degrees, or one
    angle for both axes."""
    s = np.radians(np.broadcast_to(np.asarray(sigma_deg, float), (2,)))
    return GravityEstimate(DOWN.copy(), np.diag(s * s), "level", (0, 0), reason, segments)


def _line_set(ends: np.ndarray, coef: np.ndarray, support: np.ndarray, K: np.ndarray) -> LineSet:
    n = coef @ K                                          # K^T l, as rows
    n /= np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-12)
    d = ends[:, 2:] - ends[:, :2]
    return LineSet((ends[:, :2] + ends[:, 2:]) / 2, coef[:, :2].copy(), n,
                   np.asarray(support, float), np.hypot(d[:, 0], d[:, 1]) / 2)


def _segment_coef(segs: np.ndarray) -> np.ndarray:
    """(N, 3) lines (a, b, c) through segments (N, 4), a^2 + b^2 = 1."""
    d = segs[:, 2:] - segs[:, :2]
    nrm = np.column_stack([-d[:, 1], d[:, 0]]) / np.maximum(np.hypot(d[:, 0], d[:, 1]), 1e-12)[:, None]
    return np.column_stack([nrm, -(nrm * segs[:, :2]).sum(1)])


def _lines(segments: Segments, K: np.ndarray, p: GravityParams) -> tuple[LineSet, object]:
    """(The merged lines of ``segments`` (pixels of intrinsics ``K``) with enough support,
    heaviest first, at most ``p.max_lines``; the merged lines themselves)."""
    ln = merge_collinear(segments.segs)
    ln = ln.subset(ln.support >= p.min_line_px)
    if len(ln) > p.max_lines:
        ln = ln.subset(np.arange(p.max_lines))            # heaviest first
    if p.snap and segments.gray is not None:
        ln = snap_to_edges(segments.gray.astype(np.float32), ln, p.snap_step_px)
    return _line_set(ln.ends, ln.coef, ln.support, K), ln


def _with_corners(L: LineSet, ln, segments: Segments, K: np.ndarray,
                  p: GravityParams) -> LineSet | None:
    """``L`` and the vertical corner edges rising from the floor corners of its lines
    (``corners``; weight ``corner_weight`` per pixel), or None when none is found."""
    if p.corners is None or segments.gray is None:
        return None
    cv, _ = corner_verticals(segments.gray, ln.ends, ln.support, p.corners)
    if not len(cv):
        return None
    C = _line_set(cv, _segment_coef(cv), p.corner_weight * np.hypot(*(cv[:, 2:] - cv[:, :2]).T), K)
    return LineSet(*(np.concatenate([a, b]) for a, b in zip(
        (L.mid, L.normal, L.n, L.w, L.half), (C.mid, C.normal, C.n, C.w, C.half))))


def _estimate(R, cov, masks, p: GravityParams, segments, evidence,
              alternatives=()) -> GravityEstimate:
    """The estimate of a refined frame R with its rotation covariance, or "level" with the
    reason when it cannot be used (step 4); widened over its ``alternatives`` (step 5)."""
    nv, nh = int(masks[1].sum()), int(masks[0].sum() + masks[2].sum())
    if cov is None or nv + nh < 4 or (nv == 0 and min(masks[0].sum(), masks[2].sum()) < 2):
        return level_estimate(f"too few vertical lines ({nv}) and horizontal lines ({nh}) to "
                              "tell gravity: level assumed", p.level_sigma_deg, segments)
    g = R[:, 1] / np.linalg.norm(R[:, 1])
    if g[1] < 0:
        g = -g
    pitch, roll = pitch_roll_deg(g)
    if not (p.pitch_range[0] <= pitch <= p.pitch_range[1]
            and p.roll_range[0] <= roll <= p.roll_range[1]):
        return level_estimate("the vertical direction found is outside the tilt of a "
                              "hand-held photo: level assumed", p.level_sigma_deg, segments)
    # tilt covariance: dg = dw x g; its forward part (dw x g) . zl = dw . (g x zl) is the
    # pitch change, its rightward part the roll change
    xl = np.cross(g, [0.0, 0.0, 1.0])
    xl /= np.linalg.norm(xl)
    zl = np.cross(xl, g)
    A = np.array([np.cross(g, zl), np.cross(g, xl)])
    C = A @ cov @ A.T
    floor = math.radians(p.sigma_floor_deg) ** 2
    C = p.sigma_scale ** 2 * C + floor * np.eye(2)
    est = GravityEstimate(g, C, "image", (nv, nh), None, segments, evidence)
    if est.sigma > math.radians(p.max_sigma_deg):
        return level_estimate(f"gravity from the image is too uncertain "
                              f"({math.degrees(est.sigma):.1f} deg): level assumed",
                              p.level_sigma_deg, segments)
    return with_alternatives(est, alternatives, p.alternative_weight)


def with_alternatives(est: GravityEstimate, alternatives,
                      weight: float = GravityParams.alternative_weight) -> GravityEstimate:
    """``est`` carrying ``alternatives`` (step 5), its covariance widened over them from its
    fit's, the reason said; ``est`` without alternatives when there are none."""
    base = est.fit_cov if est.fit_cov is not None else est.cov
    if not alternatives:
        return replace(est, cov=base, alternatives=(), fit_cov=None,
                       reason=None if est.alternatives else est.reason)
    return replace(est, cov=alt.widen(est.vector, base, alternatives, weight), fit_cov=base,
                   alternatives=tuple(alternatives),
                   reason=alt.describe(est.vector, alternatives))


def _frame(L: LineSet, K: np.ndarray, p: GravityParams, pitch_range, roll_range):
    """The best refined frame: the search's ``candidates`` best frames are each refined,
    and the one whose refined frame scores highest is taken; then the alternatives among
    up to ``ambiguity_candidates`` refined frames (step 5). Returns refine's (R, cov,
    masks) and the alternatives, or None when no frame fits."""
    n = max(p.candidates, p.ambiguity_candidates)
    found = search(L, K, pitch_range, roll_range, p.coarse_lines, p.inlier_deg, p.peaks,
                   p.coarse_deg, p.fine_deg, p.span_deg, p.fine_lines, n, p.candidate_ratio)
    if not found:
        return None
    done = [refine(L, K, R, p.inlier_deg, p.iterations, p.min_line_sigma_deg) for R in found]
    first = done[:p.candidates]
    if len(first) == 1:
        k = 0
    else:
        s, _ = score_frames(L, K, np.array([d[0][:, 1] for d in first]), p.inlier_deg)
        k = ties.argmax(s, rtol=ties.RTOL32)   # float32 scores
    if p.ambiguity_candidates <= 0 or len(done) == 1:
        return (*done[k], ())
    return (*done[k], _alternatives(L, K, p, done[k][0][:, 1],
                                    [d[0][:, 1] for i, d in enumerate(done)
                                     if i != k and d[1] is not None]))


def _alternatives(L: LineSet, K: np.ndarray, p: GravityParams, g, others) -> tuple:
    """The frames among ``others`` (gravities) that the lines ``L`` support nearly as well
    as ``g`` (``gravity_alternatives.distinct``)."""
    if not others:
        return ()
    s, _ = score_frames(L, K, np.array([g, *others]), p.inlier_deg)
    return alt.distinct(g, float(s[0]), zip(others, s[1:]), p.ambiguity_ratio,
                        p.distinct_deg)


def estimate_gravity(image: np.ndarray, camera: Camera,
                     params: GravityParams = GravityParams(),
                     segments: Segments | None = None) -> GravityEstimate:
    """Gravity of a photo from its vanishing directions (see the module docstring).

    Args:
        image: (H, W, 3) uint8 BGR (or (H, W) grey), the size of ``camera``.
        camera: intrinsics of the photo (its gravity is ignored).
        segments: the photo's ``segments.photo_segments`` when already detected; else
            detected here. Either way the estimate carries them (``GravityEstimate.segments``).
    Returns:
        GravityEstimate; source "level" (with the reason) when the image cannot tell.
    """
    p = params
    W = image.shape[1]
    if segments is None:
        segments = photo_segments(image)
    s = segments.width / W
    K = (camera.scaled(s) if abs(s - 1.0) > 1e-12 else camera).K
    L, ln = _lines(segments, K, p)
    est = _from_lines(L, K, p, segments, s)
    if est.source == "level" or est.lines[0] < p.corner_below:
        # few vertical lines: look for the faint vertical edges of the room's corners
        Lc = _with_corners(L, ln, segments, K, p)
        if Lc is not None:
            est_c = _from_lines(Lc, K, p, segments, s)
            if est_c.source == "image":
                return est_c
    return est


def _from_lines(L: LineSet, K: np.ndarray, p: GravityParams, segments: Segments,
                s: float) -> GravityEstimate:
    if len(L) < 3:
        return level_estimate(f"only {len(L)} straight lines in the photo: level assumed",
                              p.level_sigma_deg, segments)
    found = _frame(L, K, p, p.pitch_range, p.roll_range)
    if found is None:
        return level_estimate("no vertical or horizontal structure within the tilt a hand-held "
                              "photo has: level assumed", p.level_sigma_deg, segments)
    R, cov, masks, alternatives = found
    return _estimate(R, cov, masks, p, segments, (L, K, s), alternatives)
