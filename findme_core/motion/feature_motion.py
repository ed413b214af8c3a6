"""The feature-only estimator of planar motion (``features``, the default before layouts took
part) and what the other estimators share with it: the checks of the matches, the lifting of
matched points and the gravity-aware epipolar RANSAC.

Frames and units (DESIGN.md, ``methods``): the motion of a pair (A, B) is the pose of camera B
in A's level frame: X_A = R_y(yaw) X_B + t, t = (x, dy, z) metres, yaw radians (> 0: B turned
right of A). Per match i: unit level bearings a_i (A), b_i (B) and, where a photo's chosen
hypothesis gives one, its lifted 3D point in that photo's level frame (``features.Lifted``).

``features``: (1) verification: adaptive RANSAC over minimal samples of the gravity-aware
epipolar constraint a^T [t]x R_y b = 0 (2-point planar solver when h_A = h_B, 3-point solver
with a free vertical baseline otherwise, and 1-point pure rotations), locally optimised: yaw
and the baseline direction. With equal heights the camera moved parallel to the floor, so a
significant elevation of that baseline is the given gravity's tilt along the motion: floor
points are re-lifted on the corrected floor. (2) Metric candidates: that motion scaled by the
1-D consensus of the lifted points, and the best closed-form 2-point floor alignment of
matches lifted in both photos (another model when the epipolar consensus is spurious: few
correct matches in white rooms); the better by MSAC score (epipolar residuals of all matches
+ transfer residuals of the lifted points, pixels over their sigma) is refined by robust
Levenberg-Marquardt of (yaw, x, dy, z). Floor points first: wall points (right only when the
hypothesis is) count only when fewer than ``min_floor`` floor points agree.
"""

from __future__ import annotations

from dataclasses import replace
from typing import Callable

import numpy as np

from findme_core.errors import MotionError
from findme_core.geometry import ties
from findme_core.geometry.camera import Camera
from findme_core.geometry.planar import (_epipolar_terms, _kabsch_pairs, _rot2, _rotate, _spread,
                                         bearings, epipolar_residuals, rot_y, solve_gravity_3pt,
                                         solve_planar_2pt, transfer_residuals)
from findme_core.geometry.robust import levenberg_marquardt, msac, samples
from findme_core.motion.baselines import lifted_estimate, paper_estimate
from findme_core.motion.features import Matches
from findme_core.motion.lifting import Lifted
from findme_core.motion.model import (MotionInputs, MotionParams, PlanarMotion, motion_result,
                                      no_common_view)

Lifter = Callable[[np.ndarray], Lifted]  # match indices -> Lifted of all matches (NaN = not)


# ---------------------------------------------------------------------------- estimation
def check_matches(matches: Matches, params: MotionParams) -> None:
    """Raise ``MotionError`` when the matches are too few or did not move (identical photos)."""
    n = len(matches)
    if n < params.min_matches:
        raise MotionError(f"only {n} feature matches between the photos ({matches.n_a} and "
                          f"{matches.n_b} keypoints; need {params.min_matches}): they show "
                          "too little common texture or no common view")
    if np.mean(np.linalg.norm(matches.ua - matches.ub, axis=1) < params.min_parallax_px) > 0.8:
        raise MotionError("the two photos are identical (their features did not move), so "
                          "there is no motion to measure")


def features_estimate(matches: Matches, cam_a: Camera, cam_b: Camera, h_a: float, h_b: float,
                      lift_a: Lifter | None, lift_b: Lifter | None, method: str,
                      params: MotionParams) -> PlanarMotion:
    """Motion by the feature-based estimators ``features``, ``lifted`` and ``paper`` (see
    ``methods.estimate`` for the arguments)."""
    check_matches(matches, params)
    n = len(matches)
    a, b = bearings(cam_a, matches.ua), bearings(cam_b, matches.ub)
    pix, planar = 1.0 / np.sqrt(cam_a.fx * cam_b.fx), abs(h_a - h_b) < 1e-6
    rng = np.random.default_rng(params.seed)

    def pair(e_in, normal=None):
        sel = _lift_order(a, matches.ratio, e_in, params.max_lift)
        return MotionInputs(a, b, _inflate(lift_a, sel, n, h_a, params, normal, a),
                            _inflate(lift_b, sel, n, h_b, params,
                                     None if normal is None else rot_y(yaw).T @ normal, b),
                            float(h_a - h_b), float(h_a), pix)

    if method == "lifted":
        return _model_error(lifted_estimate(pair(np.ones(n, bool)), params, rng), params)
    yaw, t, e_in = _epipolar_ransac(a, b, planar, pix, params, rng)
    if method == "paper":
        return _model_error(paper_estimate(pair(e_in), e_in), params)
    yaw, t, e_in, sig_elev = local_optimisation(a, b, yaw, t, e_in, planar, pix, params)
    normal = None
    if planar and abs(t[1]) > 3.0 * np.sin(sig_elev):   # moved parallel to the floor: the
        normal = np.array([0.0, 1.0, 0.0]) - t[1] * t      # floor normal is orthogonal to t
        normal /= np.linalg.norm(normal)
    return _model_error(_findme(pair(e_in, normal), yaw, t, e_in, params, rng), params)


def local_optimisation(a, b, yaw, t, e_in, planar: bool, pix: float, params: MotionParams):
    """Refine (yaw, unit t) on the inliers and take them again, twice. Returns (yaw, t,
    inliers, sigma of t's elevation)."""
    for _ in range(2):
        yaw, t, sig_elev = _refine_dir(a, b, yaw, t, e_in, planar, pix)
        r, front, _, far = _epipolar_terms(a, b, yaw, t, pix)
        e_in = ((r < params.thr_px) & (front | far))[0]
    return yaw, t, e_in, sig_elev


def _model_error(m: PlanarMotion, params: MotionParams, depth_rel: float = 0.0) -> PlanarMotion:
    """``m`` with the model errors of ``params`` for its method (``MotionParams.model_errors``)
    added to its sigmas (along / across the baseline rotated into x, z, and the position
    term on both), and ``depth_rel``, the relative error its scale shares with the depths
    it rests on (``fit.common_depth_sigma``), along the baseline."""
    scale, direction_deg, yaw_deg, position_m = params.model_errors(m.method)
    base = np.hypot(m.x, m.z)
    u = np.array([m.x, m.z]) / max(base, 1e-12)
    along, across = np.hypot(scale, depth_rel) * base, np.radians(direction_deg) * base
    C = np.diag([m.sigma_x ** 2, m.sigma_z ** 2]) + along ** 2 * np.outer(u, u) \
        + across ** 2 * np.outer([-u[1], u[0]], [-u[1], u[0]]) + position_m ** 2 * np.eye(2)
    return replace(m, sigma_x=float(np.sqrt(C[0, 0])), sigma_z=float(np.sqrt(C[1, 1])),
                   sigma_yaw=float(np.hypot(m.sigma_yaw, np.radians(yaw_deg))))


def _lift_order(a, ratio, first, k: int) -> np.ndarray:
    """At most k match indices to lift: of the ``first`` ones, half the steepest below the
    horizon (likely floor, nearest first), then the most distinctive; then the others."""
    steep = [i for i in ties.order(a[:, 1]) if first[i] and a[i, 1] > 0][:k // 2]
    taken = set(steep)
    rest = [i for i in np.lexsort((ratio, ~first)) if i not in taken]
    return np.array((steep + rest)[:k], int)


def _inflate(lift: Lifter | None, sel, n: int, h: float, params: MotionParams,
             normal=None, rays=None) -> Lifted:
    """The lifted matches ``sel`` with the gravity error added to their sigma; floor points
    re-lifted on the plane normal . X = h (eq. 2 with a corrected normal) if given."""
    if lift is None:
        return Lifted.empty(n)
    L = lift(sel)
    pts = L.points.copy()
    if normal is not None:
        f = np.flatnonzero(L.floor & L.valid & (rays @ normal > 1e-3))
        pts[f] = h / (rays[f] @ normal)[:, None] * rays[f]
    d2 = pts[:, 0] ** 2 + pts[:, 2] ** 2
    return Lifted(pts, np.hypot(L.sigma, d2 / h * np.radians(params.gravity_sigma_deg)),
                  L.floor & L.valid)


def _epipolar_ransac(a, b, planar: bool, pix: float, params: MotionParams, rng):
    """Scale-free (yaw, unit t, inliers) with the best MSAC score, t signed so that the
    inliers are in front of both cameras; stops adaptively (``confidence``)."""
    n, thr = len(a), params.thr_px
    k, solver = (2, solve_planar_2pt) if planar else (3, solve_gravity_3pt)
    best, best_score, done, need = None, -1.0, 0, params.max_iters
    while done < need:
        j = samples(rng, n, k, 64)
        done += 64
        yaw, t, _ = solver(a[j], b[j])
        j0 = j[:, 0]   # and the pure rotation through each first match (no solver answer)
        yaw = np.r_[yaw, np.arctan2(a[j0, 0], a[j0, 2]) - np.arctan2(b[j0, 0], b[j0, 2])]
        t = np.vstack([t, np.tile([1.0, 0.0, 0.0], (len(j0), 1))])
        # cheirality only removes inliers: the residuals' score bounds the full one, so only
        # the best 8 candidates of the batch get the depths
        top = ties.order(msac(np.abs(epipolar_residuals(yaw, t, a, b)) / pix, thr))[:8]
        yaw, t = yaw[top], t[top]
        r, front, back, far = _epipolar_terms(a, b, yaw, t, pix)
        flip = (back & (r < thr)).sum(1) > (front & (r < thr)).sum(1)
        t[flip] = -t[flip]
        inl = (r < thr) & (far | np.where(flip[:, None], back, front))
        score = msac(np.where(inl, r, thr), thr)
        i = ties.argmax(score)
        if ties.beats(score[i], best_score):   # a tie keeps the model found first
            best, best_score = (float(yaw[i]), t[i], inl[i]), score[i]
            w = max(inl[i].sum(), k) / n
            need = min(params.max_iters,
                       int(np.log(1 - params.confidence) / np.log(max(1e-12, 1 - w ** k))) + 1)
    if best is None or best[2].sum() < min(params.min_inliers, n):
        raise no_common_view(0 if best is None else int(best[2].sum()), n)
    return best


def _score(P: MotionInputs, yaw, t, use, thr: float):
    """MSAC score of C metric motions, yaw (C,), t (C, 3): epipolar residuals of all matches
    plus transfer residuals of the lifted points in ``use`` (masks of A, B). Returns (score
    (C,), epipolar inliers (C, M), lifted-A inliers (C, M), lifted-B inliers (C, M))."""
    yaw, t = np.atleast_1d(yaw), np.atleast_2d(t)
    r, front, _, far = _epipolar_terms(P.a, P.b, yaw, t, P.pix)
    e_in = (r < thr) & (front | far)
    score, ins = msac(np.where(e_in, r, thr), thr), []
    for L, u, rays, into_b in ((P.la, use[0], P.b, True), (P.lb, use[1], P.a, False)):
        i, m = np.flatnonzero(u), np.zeros(e_in.shape, bool)
        if len(i):
            rt = transfer_residuals(yaw, t, L.points[i], L.sigma[i], rays[i], into_b, P.pix)
            m[:, i] = rt < thr
            score = score + msac(rt, thr)
        ins.append(m)
    return score, e_in, ins[0], ins[1]


def _scale(P: MotionInputs, yaw, t, e_in, use) -> float | None:
    """Baseline length along the unit t on which most lifted epipolar inliers agree (1-D
    consensus; each point's s puts it on the other photo's ray; relative sigma = relative
    depth sigma (+) one pixel over the parallax); None without a lifted inlier."""
    s, sg = [], []
    for L, u, into_b in ((P.la, use[0], True), (P.lb, use[1], False)):
        i = np.flatnonzero(e_in & u)
        pts = L.points[i]
        c, v = (pts, _rotate(np.atleast_1d(yaw), P.b[i])[0]) if into_b else \
            (-_rotate(np.atleast_1d(yaw), pts)[0], P.a[i])
        tv = v @ t
        den = np.maximum(1.0 - tv ** 2, 1e-9)
        si = (c @ t - tv * np.sum(v * c, 1)) / den
        rel = np.hypot(L.sigma[i] / np.linalg.norm(pts, axis=1), 2.0 * P.pix / np.sqrt(den))
        s.append(si)
        sg.append(rel * np.abs(si) + 1e-3)
    return _consensus(np.concatenate(s), np.concatenate(sg))


def _consensus(s, sg) -> float | None:
    """The weighted mean of the scales s (K,) (sigmas sg) that agree with the best supported
    one (``_scale``); None without a positive one."""
    pos = s > 0
    s, sg = s[pos], sg[pos]
    if len(s) == 0:
        return None
    score = np.maximum(0.0, 1.0 - ((s[None, :] - s[:, None]) / (2.5 * sg[None, :])) ** 2).sum(1)
    ok = np.abs(s - s[ties.argmax(score)]) < 2.5 * sg
    return float(np.sum(s[ok] / sg[ok] ** 2) / np.sum(1.0 / sg[ok] ** 2))


def _refine_dir(a, b, yaw, t, e_in, planar: bool, pix: float, sigma_elev=np.radians(3.0)):
    """Robust LM of (yaw, azimuth, elevation) of the unit baseline on the inliers' epipolar
    residuals (pixels); a level prior on the elevation when h_A = h_B. Returns (yaw, unit
    t, sigma of the elevation)."""
    ae, be = a[e_in], b[e_in]   # indexed once, not per residual evaluation
    unit = lambda q: np.stack([np.sin(q[..., 1]) * np.cos(q[..., 2]), np.sin(q[..., 2]),  # noqa
                               np.cos(q[..., 1]) * np.cos(q[..., 2])], -1)

    def resid(q):  # (C, 3) -> (C, R)
        r = epipolar_residuals(q[:, 0], unit(q), ae, be) / pix
        return np.concatenate([r, q[:, 2:3] / sigma_elev], 1) if planar else r

    q0 = np.array([yaw, np.arctan2(t[0], t[2]), np.arcsin(np.clip(t[1], -1.0, 1.0))])
    q, cov = levenberg_marquardt(resid, q0, n_prior=int(planar))
    return float(q[0]), unit(q), float(np.sqrt(cov[2, 2]))


def _refine(P: MotionInputs, yaw, t, e_in, ta_in, tb_in):
    """Robust LM of p = (yaw, tx, ty, tz) (radians, metres) on the epipolar residuals of the
    inliers ``e_in`` and the transfer residuals of the lifted inliers (``ta_in`` A into B,
    ``tb_in`` B into A), pixels; Gaussian prior ty = dy, 2 cm + 3 % of the baseline (a floor
    or road that is not quite level, a hand-held phone). Returns (p, covariance)."""
    ia, ib = np.flatnonzero(ta_in), np.flatnonzero(tb_in)
    ae, be = P.a[e_in], P.b[e_in]   # indexed once, not per residual evaluation
    lifted = [(P.la.points[ia], P.la.sigma[ia], P.b[ia], True),
              (P.lb.points[ib], P.lb.sigma[ib], P.a[ib], False)]
    spread = [_spread(yaw, t, *x, P.pix) for x in lifted]   # at the start: barely changes

    def resid(p):  # (C, 4) -> (C, R)
        y, tq = p[:, 0], p[:, 1:4]
        return np.concatenate(
            [epipolar_residuals(y, tq, ae, be) / P.pix]
            + [transfer_residuals(y, tq, *x, P.pix, sp) for x, sp in zip(lifted, spread)]
            + [((tq[:, 1] - P.dy) / (0.02 + 0.03 * np.hypot(tq[:, 0], tq[:, 2])))[:, None]], 1)

    return levenberg_marquardt(resid, np.array([yaw, *t]), n_prior=1)


def _kabsch_candidate(P: MotionInputs, use, params: MotionParams, rng):
    """Best 2-point floor alignment of matches lifted in both photos: cheap 2-D agreement of
    the lifted pairs first, then the full score of the best 32. None if fewer than 2."""
    both = np.flatnonzero(use[0] & use[1])
    if len(both) < 2:
        return None
    A, B = P.la.points[both][:, [0, 2]], P.lb.points[both][:, [0, 2]]
    yaw, t2 = _kabsch_pairs(A, B, samples(rng, len(both), 2, params.max_iters))
    sig = np.maximum(np.hypot(P.la.sigma[both], P.lb.sigma[both]), 0.02)
    d = np.linalg.norm(A - _rot2(yaw[:, None], B) - t2[:, None], axis=-1) / sig
    top = ties.order(msac(d, 3.0))[:32]
    t = np.column_stack([t2[top, 0], np.full(len(top), P.dy), t2[top, 1]])
    i = ties.argmax(_score(P, yaw[top], t, use, params.thr_px)[0])
    return float(yaw[top][i]), t[i]


def _findme(P: MotionInputs, yaw, t, e_in, params: MotionParams, rng) -> PlanarMotion:
    """The better (full score) of the scaled epipolar motion and the best lifted alignment,
    refined twice (inliers re-taken). Floor points first; wall points too when fewer than
    ``min_floor`` floor points agree with it (wrong matches on a repetitive carpet are
    floor points too, so they are counted after the fit)."""
    for walls in (False, True):
        use = P.usable(walls)
        s = _scale(P, yaw, t, e_in, use)
        cands = ([(yaw, s * t)] if s is not None else []) + \
            [c for c in [_kabsch_candidate(P, use, params, rng)] if c is not None]
        if not cands:
            continue
        scores = _score(P, [c[0] for c in cands], [c[1] for c in cands], use, params.thr_px)[0]
        best = cands[ties.argmax(scores)]   # a tie: the scaled epipolar motion
        p = np.array([best[0], *best[1]])
        for _ in range(2):
            _, e2, ta, tb = (m[0] for m in _score(P, p[0], p[1:], use, params.thr_px))
            if e2.sum() < params.min_inliers or not (ta.any() or tb.any()):
                break
            p, cov = _refine(P, p[0], p[1:], e2, ta, tb)
        else:
            _, e2, ta, tb = (m[0] for m in _score(P, p[0], p[1:], use, params.thr_px))
            if e2.sum() >= params.min_inliers and (walls or (ta | tb).sum() >= params.min_floor):
                return motion_result(p[[0, 1, 3]], p[2], cov[np.ix_([0, 1, 3], [0, 1, 3])],
                               e2 | ta | tb, int(ta.sum() + tb.sum()), "features")
    raise MotionError("no matched point lies on the floor or on a chosen wall consistently "
                      "with the motion in either photo, so the distance between the photos "
                      "cannot be measured")



