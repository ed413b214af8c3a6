"""Ground-wall boundary hypotheses from one photo (paper step 2, extended).

Pipeline of our method (``generate``):

1. segments (LSD) -> collinear merge -> classification in the level frame (``lines``);
2. edge support of every floor-candidate line, per column (``support``);
3. best boundary through every corner / occluding step / top crossing (``search``);
4. re-ranking by edge score plus colour separability of the floor region (``appearance``),
   near-duplicate suppression, best first.

A hypothesis is a polyline from u = 0 to u = W - 1; the floor is the region below it. Its
segments are tagged WALL (a wall or object face stands on it), STEP (occluding edge) or OPEN
(the floor continues past the top border), which the scene model uses.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from findme_core.errors import InputError
from findme_core.geometry import ties
from findme_core.geometry.camera import Camera
from findme_core.single.appearance import FloorLikelihood, RegionStats, to_lab
from findme_core.single.flat import no_floor_first
from findme_core.single.lines import Lines, LineKind, classify, merge_collinear
from findme_core.single.paths import path_features, path_pieces, path_polyline, path_rows
from findme_core.single.ranking import (IDX, N_ADDITIVE, RANK_WEIGHTS, SEARCH_WEIGHTS,
                                        RankWeights, feature_matrix)
from findme_core.single.refine import SnapParams, prefetch, snap_polyline
from findme_core.single.search import (SearchParams, best_paths, events, rewards, track_rows,
                                       track_tables, with_region)
from findme_core.single.segments import (LSD_SCALE, MIN_SEGMENT_PX, Segments, detect_segments,
                                         horizon_top_row)
from findme_core.single.support import EdgeField, SupportParams, tabulate


@dataclass(frozen=True)
class Hypothesis:
    """One ground-wall boundary.

    Attributes:
        polyline: (M, 2) pixel vertices (u, v), u non-decreasing from 0 to W - 1; v may lie
            outside the image (the boundary is hidden below or above it there).
        kinds: (M - 1,) SegKind of each segment.
        score: ranking score (higher is better).
        support: fraction of the in-image WALL length on edge evidence (the paper's score).
        flat: share of its WALL columns across which the photo's colour does not step
            (``flat.flat_share``; measured for the best boundary found; 0: not measured).
        smooth: share of its WALL columns over a smooth band, in a photo whose horizon is
            in view (``flat.smooth_share``; measured as ``flat``).
    """

    polyline: np.ndarray
    kinds: np.ndarray
    score: float
    support: float = 0.0
    flat: float = 0.0
    smooth: float = 0.0


@dataclass(frozen=True)
class HypothesisSet:
    """Ranked hypotheses of one photo, best first, with the lines that produced them."""

    width: int
    height: int
    hypotheses: list[Hypothesis]
    lines: Lines
    kinds: np.ndarray
    reason: str | None = None  # why the list is empty, if it is
    timing_ms: dict = field(default_factory=dict)


@dataclass(frozen=True)
class HypothesisParams:
    segment_method: str = "lsd"
    lsd_scale: float = LSD_SCALE
    below_horizon_only: bool = True  # detect lines only below the horizon (less work)
    min_segment_px: float = MIN_SEGMENT_PX
    min_line_support_px: float = 25.0
    max_lines: int = 30
    horizon_margin: float = 0.01
    rerank_top: int = 120
    seed_top: int = 120
    substeps: int = 1
    likelihood_scale: int = 8
    nms_px: float = 3.0
    snap: bool = True
    snap_params: SnapParams = SnapParams()
    support: SupportParams = SupportParams()
    search: SearchParams = SearchParams()
    search_weights: RankWeights = SEARCH_WEIGHTS
    weights: RankWeights = RANK_WEIGHTS


def column_rows(polyline: np.ndarray, height: int, cols: np.ndarray) -> np.ndarray:
    """Row of the polyline at the given columns, clipped to [0, height]."""
    return np.clip(np.interp(cols, polyline[:, 0], polyline[:, 1]), 0.0, float(height))


def suppress_duplicates(rows: np.ndarray, order: np.ndarray, nms_px: float, max_n: int) -> list[int]:
    """Greedy non-maximum suppression on (K, C) clipped boundary rows: skip a candidate whose
    rows differ from a kept one by less than ``nms_px`` on average. Each kept candidate is
    compared with those after it, once (at most ``max_n`` comparisons of K rows)."""
    rows = rows[order]
    free = np.ones(len(rows), bool)     # not near any kept one (the distance is symmetric)
    kept: list[int] = []
    i = 0
    while i < len(rows):
        kept.append(i)
        if len(kept) >= max_n:
            break
        free[i + 1:] &= np.abs(rows[i + 1:] - rows[i]).mean(1) >= nms_px
        nxt = np.flatnonzero(free[i + 1:])
        if len(nxt) == 0:
            break
        i += 1 + int(nxt[0])
    return [int(order[k]) for k in kept]


def vertical_in_floor(rows: np.ndarray, verticals: np.ndarray, n_samples: int = 8,
                      tol_px: float = 4.0) -> np.ndarray:
    """(K,) length in pixels of 3D-vertical segments lying inside each candidate's floor
    region (more than ``tol_px`` below its polyline). A floor has nothing standing on it
    inside the region the hypothesis calls floor, so long verticals there (cabinet doors
    under a countertop taken for the floor) count against it.

    Args:
        rows: (K, W) boundary row of each candidate at every column.
        verticals: (V, 4) segments.
    """
    if len(verticals) == 0:
        return np.zeros(len(rows))
    t = (np.arange(n_samples) + 0.5) / n_samples
    seg = np.asarray(verticals, float)
    pts = seg[:, None, :2] + t[None, :, None] * (seg[:, None, 2:] - seg[:, None, :2])
    pts = pts.reshape(-1, 2)
    w = np.repeat(np.hypot(*(seg[:, 2:] - seg[:, :2]).T) / n_samples, n_samples)
    cols = np.clip(np.round(pts[:, 0]), 0, rows.shape[1] - 1).astype(int)
    inside = rows[:, cols] + tol_px < pts[:, 1][None, :]
    return ties.matvec(inside.astype(float), w)   # a ranking feature: without BLAS


def floor_candidates(image: np.ndarray, camera: Camera, params: HypothesisParams,
                     segments: Segments | None = None, top: int | None = None):
    """Detect (or take from ``segments``), merge and classify lines.

    Args:
        segments: a whole-image detection of this image (``Segments.detect``), used when it
            is what ``params`` would detect: then only its part below the horizon is taken.
        top: the first image row searched when known (default: ``horizon_top_row`` if
            ``params.below_horizon_only``, else 0).
    Returns:
        (Lines, kinds (N,), indices of floor-candidate lines, indices of vertical lines).
    """
    if top is None:
        top = horizon_top_row(camera) if params.below_horizon_only else 0
    H, W = image.shape[:2]
    if (segments is not None and params.segment_method == "lsd"
            and segments.fits(W, H, params.lsd_scale, params.min_segment_px)):
        segs = segments.below(top, params.min_segment_px)
    else:
        segs = detect_segments(image, params.segment_method, params.min_segment_px,
                               lsd_scale=params.lsd_scale, top_row=top)
    lines = merge_collinear(segs)
    kinds = classify(lines, camera, horizon_margin=params.horizon_margin)
    floor = np.isin(kinds, (LineKind.LEFT, LineKind.FRONT, LineKind.RIGHT))
    floor &= lines.support >= params.min_line_support_px
    floor &= np.abs(lines.coef[:, 1]) > 0.05
    cand = np.nonzero(floor)[0][: params.max_lines]
    vert = np.nonzero(kinds == LineKind.VERTICAL)[0]
    return lines, kinds, cand, vert


def _check_image(image: np.ndarray, camera: Camera) -> None:
    if not isinstance(image, np.ndarray) or image.dtype != np.uint8 or image.ndim not in (2, 3):
        raise InputError("image must be a uint8 HxW or HxWx3 array, got "
                         f"{getattr(image, 'dtype', type(image))} {getattr(image, 'shape', '')}")
    H, W = image.shape[:2]
    if (W, H) != (camera.width, camera.height):
        raise InputError(f"image is {W}x{H} but the camera is {camera.width}x{camera.height}")


def generate(image: np.ndarray, camera: Camera, max_n: int = 10,
             params: HypothesisParams = HypothesisParams(), clock=None,
             debug: dict | None = None, segments: Segments | None = None) -> HypothesisSet:
    """All steps for one photo: lines -> candidates -> scored, ranked hypotheses.

    Args:
        image: (H, W, 3) uint8 BGR or (H, W) grey, the size of ``camera``.
        camera: intrinsics and gravity of the photo.
        max_n: at most this many hypotheses are returned.
        clock: optional zero-argument function returning seconds, for ``timing_ms``
            (the core reads no clock itself).
        segments: the image's whole-frame segments when already detected (a photo whose
            gravity came from them, ``vanishing.estimate_gravity``); else detected here.
    """
    _check_image(image, camera)
    H, W = image.shape[:2]
    t = [clock()] if clock else []
    top = horizon_top_row(camera) if params.below_horizon_only else 0
    lines, kinds, cand, vert = floor_candidates(image, camera, params, segments, top)
    if clock:
        t.append(clock())
    if len(cand) == 0:
        reason = ("no straight lines found in the image" if len(lines) == 0 else
                  "no line below the horizon could be a ground-wall boundary")
        return HypothesisSet(W, H, [], lines, kinds, reason, _timing(t, ("lines",)))
    coef = lines.coef[cand]
    lab = to_lab(image)
    field = EdgeField(image, params.support, color=lab, top_row=top)
    table = tabulate(field, coef, params.substeps)
    if clock:
        t.append(clock())
    sp, w, ws = params.search, params.weights.vector(), params.search_weights.vector()
    rows_t = track_rows(table, H)
    verts = lines.ends[vert]
    stats = RegionStats(lab)
    F, valid = track_tables(table, camera, sp, front=kinds[cand] == LineKind.FRONT,
                            texture=field.band_texture)
    ev = events(coef, rows_t, valid, verts, camera, sp)
    if params.seed_top <= 1:  # seed = the search's best path (no features: no `far` test)
        paths = best_paths(rewards(F, valid, ws[:N_ADDITIVE]), valid, ev, -ws[IDX["corners"]],
                           -ws[IDX["steps"]], limit=1)
        cands, seed = None, (paths[0] if paths else None)
    else:
        cands, seed = _search_and_rank(F, valid, ev, coef, stats, verts, ws, params, W, H,
                                       rows_t, params.seed_top)
    if ws[IDX["region"]] != 0 and seed is not None:
        # the colour model is seeded by the best under the *search* weights that puts no wall
        # implausibly far, so the candidate pool does not depend on the re-ranking weights
        # (no feedback when fitting them)
        best = path_polyline(seed[1], seed[2], ev, coef, W, H)[0]
        fl = FloorLikelihood(lab, column_rows(best, H, np.arange(W, dtype=float)),
                             scale=params.likelihood_scale)
        if fl.valid:  # second pass with colour evidence inside the search
            F = with_region(F, fl.below(rows_t))
            cands = None
    if cands is None:
        cands, _ = _search_and_rank(F, valid, ev, coef, stats, verts, ws, params, W, H,
                                    rows_t, params.rerank_top, seed=False)
    ranked = _ranked(cands, w)
    if clock:
        t.append(clock())
    if not ranked:
        return HypothesisSet(W, H, [], lines, kinds,
                             "no boundary hypothesis fits below the horizon",
                             _timing(t, ("lines", "support", "search")))
    if debug is not None:  # for tools/fit_ranker.py: every candidate, scored, with its polyline
        debug["ranked"] = ranked
        debug["polylines"] = [path_polyline(r[1][1], r[1][2], ev, coef, W, H)[0] for r in ranked]
    rows = np.array([r[2] for r in ranked])
    keep = suppress_duplicates(rows, np.arange(len(ranked)), params.nms_px, max_n)
    hyps = []
    cache: dict = {}
    built_all = [path_polyline(ranked[i][1][1], ranked[i][1][2], ev, coef, W, H) for i in keep]
    if params.snap:   # every line's band measured at once, then each polyline snapped
        prefetch(lab, camera, built_all, params.snap_params, cache)
    for i, built in zip(keep, built_all):
        poly, kinds_i = built[0], built[1]
        if params.snap:
            poly = snap_polyline(lab, camera, poly, kinds_i, params.snap_params, cache, built[2])
        f = ranked[i][3]
        hyps.append(Hypothesis(poly, kinds_i, float(ranked[i][0]), float(f[IDX["fraction"]])))
    hyps = no_floor_first(hyps, lab, max_n, field.band_texture, horizon_top_row(camera),
                          sp.smooth_texture)
    if clock:
        t.append(clock())
    return HypothesisSet(W, H, hyps, lines, kinds, None,
                         _timing(t, ("lines", "support", "search", "rank")))


def _search_and_rank(F, valid, ev, coef, stats, verts, ws, params, W, H, rows_t, top: int,
                     seed: bool = True):
    """Best paths under search weights ``ws`` and their features for re-ranking
    (``_ranked``); the answer "no floor visible" is among them when the search found it or
    when the search's best boundary lies partly implausibly far (``search.farness``).

    Returns:
        ((paths, rows (K, len(stats.cols)) at ``stats.cols``, features (K, len(FEATURES)))
         or () without paths; the seed, or None unless ``seed``). A path is (score, start
         track, event chain). The seed is the best path under ``ws`` among those with no
         wall implausibly far (``far`` 0), when there is one: the colour model it seeds
         takes everything under it for floor, so a far seed (a poster's top edge, 40 m away
         for a camera pitched 28 deg down) makes the wall below it floor and endorses
         itself: the rendered 5 x 4 m room's photo facing a wall 1 m away ranked a poster's
         lower edge (score 6.36) over the wall's base (3.42).
    """
    A = rewards(F, valid, ws[:N_ADDITIVE])
    paths = best_paths(A, valid, ev, -ws[IDX["corners"]], -ws[IDX["steps"]], limit=top)
    if not paths:
        return (), None
    found = len(paths)
    none = len(A) - 1   # the BOTTOM track alone: "no floor visible"
    if (not any(p[1] == none and not p[2] for p in paths)
            and path_features(path_pieces(paths[:1], ev, W), F, 1)[0, IDX["far"]] > 0):
        # the search's best boundary puts a wall implausibly far (a counter top's edge seen
        # level): then "no floor visible" is a candidate even when 120 paths score higher
        paths.append((float(A[none, -1] - A[none, 0]), none, ()))
    pieces = path_pieces(paths, ev, W)
    full_rows = np.clip(path_rows(pieces, rows_t, len(paths)), 0.0, float(H))
    rows = full_rows[:, stats.cols]
    feats = feature_matrix(path_features(pieces, F, len(paths)), stats.gain(rows),
                           vertical_in_floor(full_rows, verts), rows, W, H)
    best = None
    if seed:   # among the search's own paths, one that puts no wall implausibly far
        sc = np.asarray(ties.matvec(feats[:found], ws), float)
        near = feats[:found, IDX["far"]] <= 0.0
        best = paths[ties.argmax(np.where(near, sc, np.nan) if near.any() else sc)]
    return (paths, rows, feats), best


def _ranked(cands, w):
    """list of (score, path, rows, features) of ``_search_and_rank``'s candidates under the
    weights ``w``, best first (empty without candidates). Scores without BLAS, ties (equal
    within ties.RTOL) in the search's order: the same ranking on every CPU."""
    if not cands:
        return []
    paths, rows, feats = cands
    score = ties.matvec(feats, w)
    return [(float(score[i]), paths[i], rows[i], feats[i]) for i in ties.order(score)]


def _timing(t, names):
    return {n: 1e3 * (b - a) for n, a, b in zip(names, t[:-1], t[1:])}
