"""How well planar motions of photo B in photo A's level frame explain a pair's evidence,
and their refinement: the scoring half of the ``findme`` estimator (``estimator``).

A motion is yaw (radians, > 0: B turned right of A) and t = (x, dy, z) (metres), X_A =
R_y(yaw) X_B + t (DESIGN.md). Its score adds: the matches (MSAC of the epipolar residuals,
pixels, and of the lifted points' transfer residuals, floor points first), the layouts
(``register.scores``, the best candidate pair, never below ``layout_floor``), the two
photos' room orientations (a yaw that agrees with them modulo 90 deg) and a prior on the
baseline. ``Fit.refine`` is robust Levenberg-Marquardt of (yaw, x, dy, z) on all of them.
Pure numpy.
"""

from __future__ import annotations

import numpy as np

from findme_core.geometry import ties
from findme_core.geometry.planar import (_dot, _epipolar_terms, _norm, _rotate, _spread,
                                         epipolar_residuals, known_yaw_terms, transfer_residuals)
from findme_core.geometry.robust import levenberg_marquardt, msac
from findme_core.motion import register
from findme_core.motion.feature_motion import _consensus
from findme_core.motion.model import MotionInputs, MotionParams


def wrap90(x):
    """Angle difference modulo a quarter turn, in [-pi/4, pi/4)."""
    return (np.asarray(x) + np.pi / 4) % (np.pi / 2) - np.pi / 4


def known_yaw_score(a, Rb, m, T, pix: float, thr: float, ab=None, far=None):
    """MSAC score (C,) and inliers (C, M) of C unit baselines T (C, 3) at one yaw (bearings
    a (M, 3), B's bearings turned into A's frame Rb, m = Rb x a, and optionally their
    a . Rb and no-parallax mask (M,) from ``Turned``; ``planar.known_yaw_terms``)."""
    r, front, far = known_yaw_terms(a, Rb, m, T, pix, ab, far)
    inl = (r < thr) & (front | far)
    return msac(np.where(inl, r, thr), thr), inl


def scene_depth(P: MotionInputs, layouts_a, layouts_b) -> float | None:
    """Depth scale of a pair's scene, metres: the median horizontal distance of the two
    photos' boundary samples (their first layouts) and lifted points (``P.la``, ``P.lb``),
    weighted by 1 / sigma^2 (a boundary near the horizon is far and says little); None
    without either."""
    d, w = [np.zeros(0)], [np.zeros(0)]
    for lays, L in ((layouts_a, P.la), (layouts_b, P.lb)):
        d.append(np.hypot(L.points[L.valid, 0], L.points[L.valid, 2]))
        w.append(L.sigma[L.valid] ** -2.0)
        if lays:
            k = (lays[0].kind == 0) & np.isfinite(lays[0].range)
            d.append(lays[0].range[k])
            w.append(lays[0].sigma[k] ** -2.0)
    d, w = np.concatenate(d), np.concatenate(w)
    if len(d) == 0:
        return None
    o = np.argsort(d)
    c = np.cumsum(w[o])
    return float(d[o][np.searchsorted(c, 0.5 * c[-1])])


def common_depth_sigma(lifted) -> float:
    """Relative 1-sigma that a baseline's length shares with the depths of the lifted points
    it rests on.

    A photo's lifted points are not independent: the camera height, the gravity and the
    boundary of each wall move all of them together (``uncertainty.point_sigmas``), and
    scaling every depth of both photos by (1 + e) scales the baseline by (1 + e) and leaves
    every image residual as it was. The refinement treats the points as independent, so its
    sigma of the length shrinks as 1 / sqrt(n); here each photo's points are taken as fully
    correlated (the conservative limit): the photo's error is the weighted mean of its
    points' relative sigmas s_i (weights w_i = 1 / s_i^2, as the fit weighs them), and the
    two photos' independent errors combine by the weight each photo has in the length:
    sqrt((W_A e_A)^2 + (W_B e_B)^2) / (W_A + W_B), W = sum of w_i.

    Args:
        lifted: per photo, (points (N, 3) metres, sigmas (N,) metres) of the lifted points
            that fix the scale (the answer's transfer inliers); N may be 0.
    Returns:
        The relative sigma (0 when no point is lifted: the scale then rests on the layouts,
        whose error the model terms carry).
    """
    W, E = [], []
    for pts, sig in lifted:
        if len(pts) == 0:
            continue
        s = np.asarray(sig, float) / np.maximum(np.linalg.norm(pts, axis=1), 1e-9)
        w = 1.0 / np.maximum(s, 1e-6) ** 2
        W.append(w.sum())
        E.append(float((w * s).sum() / w.sum()))
    if not W:
        return 0.0
    W, E = np.array(W), np.array(E)
    return float(np.sqrt(np.sum((W * E) ** 2)) / W.sum())


class Turned:
    """B's bearings b (M, 3) turned into A's level frame at a yaw, with what scoring at that
    known yaw needs of them, computed once per yaw (the candidates, the directions and the
    scores of one run share a few yaws): ``turned(yaw)`` -> (Rb (M, 3), m = Rb x a (M, 3),
    a . Rb (M,), no-parallax mask (M,), as ``planar.known_yaw_terms``)."""

    def __init__(self, a, b, pix: float):
        self.a, self.b, self.pix, self.memo = a, b, pix, {}

    def __call__(self, yaw):
        key = float(yaw)
        if key not in self.memo:
            Rb = _rotate(np.array([key]), self.b)[0]
            m = np.cross(Rb, self.a)
            self.memo[key] = (Rb, m, _dot(self.a, Rb), _norm(m) / self.pix < 1.0)
        return self.memo[key]


class YawScale:
    """``feature_motion._scale`` of many baseline directions at a few yaws: the terms that
    depend on the yaw only (the lifted points and rays turned, their dot products, the
    points' relative sigmas) computed once per yaw; the same arithmetic, the same numbers.
    ``scale(yaw, t, e_in, use)`` as ``_scale(P, yaw, t, e_in, use)``."""

    def __init__(self, P: MotionInputs, turned: Turned):
        self.P, self.turned, self.memo = P, turned, {}

    def _terms(self, yaw):
        key = float(yaw)
        if key not in self.memo:
            P, out = self.P, []
            Rb = self.turned(key)[0]
            for L, into_b in ((P.la, True), (P.lb, False)):
                c, v = (L.points, Rb) if into_b else \
                    (-_rotate(np.atleast_1d(key), L.points)[0], P.a)
                with np.errstate(invalid="ignore"):   # rows without 3D: NaN, never used
                    out.append((c, v, np.sum(v * c, 1),
                                L.sigma / np.linalg.norm(L.points, axis=1)))
            self.memo[key] = out
        return self.memo[key]

    def __call__(self, yaw, t, e_in, use) -> float | None:
        s, sg = [], []
        for (c, v, vc, rs), u in zip(self._terms(yaw), use):
            i = np.flatnonzero(e_in & u)
            if len(i) == 0:   # no lifted inlier in this photo
                continue
            tv = v[i] @ t
            den = np.maximum(1.0 - tv ** 2, 1e-9)
            si = (c[i] @ t - tv * vc[i]) / den
            rel = np.hypot(rs[i], 2.0 * self.P.pix / np.sqrt(den))
            s.append(si)
            sg.append(rel * np.abs(si) + 1e-3)
        return _consensus(np.concatenate(s), np.concatenate(sg)) if s else None


class Fit:
    """The evidence of one pair and how motions fit it.

    Args:
        P: bearings and lifted points of the matches (``MotionInputs``).
        la, lb: candidate layouts of A and of B, the chosen ones first.
        orient: (yaw the orientations give modulo 90 deg, their weakest support) or None.
        depth: the scene's depth scale, metres, or None.
        params: estimator settings; rp: the layout terms' settings.
    """

    def __init__(self, P: MotionInputs, la, lb, orient, depth, params: MotionParams,
                 rp: register.RegisterParams, turned: Turned | None = None):
        self.P, self.la, self.lb, self.orient, self.depth = P, la, lb, orient, depth
        self.turned = Turned(P.a, P.b, P.pix) if turned is None else turned
        self.p, self.rp, self.dy, self.n = params, rp, P.dy, len(P.a)
        self.floor_first = None   # decided on the first motions scored

    def features(self, yaw, t3, epipolar: bool = True):
        """(C,) MSAC of the epipolar residuals of all matches (unless not ``epipolar``) and
        the transfer residuals of the lifted points (pixels over their spread, the spread
        capped at 3): floor points only once some motion has ``min_floor`` of them agreeing
        (``self.floor_first``: a wall point is right only when its wall is), else wall
        points too."""
        if self.n == 0:
            return np.zeros(len(yaw))
        thr, P = self.p.thr_px, self.P
        score = np.zeros(len(yaw))
        T = t3 / np.maximum(np.linalg.norm(t3, axis=1, keepdims=True), 1e-12)
        for y in np.unique(yaw) if epipolar else ():   # candidates come in groups of one yaw
            k = yaw == y
            Rb, m, ab, far = self.turned(y)
            score[k] = known_yaw_score(P.a, Rb, m, T[k], P.pix, thr, ab, far)[0]
        floor, wall, n_floor = np.zeros(len(yaw)), np.zeros(len(yaw)), np.zeros(len(yaw))
        for L, rays, into_b in ((P.la, P.b, True), (P.lb, P.a, False)):
            i = np.flatnonzero(L.valid)
            if len(i):
                x = (L.points[i], L.sigma[i], rays[i], into_b)
                rt = transfer_residuals(yaw, t3, *x, P.pix, max_spread=3.0)
                f = L.floor[i]
                floor += msac(rt[:, f], thr)
                wall += msac(rt[:, ~f], thr)
                n_floor += (rt[:, f] < thr).sum(1)
        if self.floor_first is None:
            self.floor_first = bool(n_floor.max(initial=0) >= self.p.min_floor)
        return score + floor + (0.0 if self.floor_first else wall)

    def layouts(self, yaw, t2):
        """(C,) best layout score over the candidate layout pairs (a layout that is not the
        chosen one loses ``rank_penalty`` per step; layouts that disagree add nothing rather
        than count against: a wrong hypothesis must not outvote the matches), and the pair
        (i, j) of each."""
        best, which = np.full(len(yaw), self.p.layout_floor), np.full((len(yaw), 2), -1)
        for i, la in enumerate(self.la):
            for j, lb in enumerate(self.lb):
                s = register.scores(la, lb, yaw, t2, self.rp) - self.p.rank_penalty * (i + j)
                better = ties.beats(s, best)   # a tie keeps the pair met first
                best = np.where(better, s, best)
                which[better] = (i, j)
        return best, which

    def orientation(self, yaw):
        if self.orient is None:
            return np.zeros(len(yaw))
        d = wrap90(self.orient[0] - yaw) / (3.0 * np.radians(self.p.orientation_sigma_deg))
        return self.p.orientation_weight * self.orient[1] * np.maximum(0.0, 1.0 - d * d)

    def baseline(self, t3):
        """(C,) prior on the baseline: two photos sharing a view are rarely taken more than
        ``baseline_depths`` times the depth of what they see apart (``self.depth``: the
        median horizontal distance of the boundary samples and lifted points of the photo
        that sees farther); beyond, ``baseline_weight`` per unit of the excess ratio."""
        if self.depth is None:
            return np.zeros(len(t3))
        ratio = np.hypot(t3[:, 0], t3[:, 2]) / (self.p.baseline_depths * self.depth)
        return -self.p.baseline_weight * np.maximum(0.0, ratio - 1.0)

    def scale_score(self, yaw, t3):
        """(C,) the part of ``score`` that depends on the baseline's length: the lifted
        points' transfer, the layouts and the baseline prior (the epipolar residuals and the
        orientations see only the yaw and the baseline's direction)."""
        yaw, t3 = np.atleast_1d(np.asarray(yaw, float)), np.atleast_2d(t3)
        return (self.features(yaw, t3, epipolar=False) + self.layouts(yaw, t3[:, [0, 2]])[0]
                + self.baseline(t3))

    def score(self, yaw, t3):
        """(C,) total score of C motions (yaw (C,), t (C, 3)) and their layout pairs."""
        yaw = np.atleast_1d(np.asarray(yaw, float))
        t3 = np.atleast_2d(t3)
        if len(yaw) > 1:   # candidates repeat (a scale found twice): each scored once
            _, first, back = np.unique(np.column_stack([yaw, t3]), axis=0, return_index=True,
                                       return_inverse=True)
            if len(first) < len(yaw):
                o = np.sort(first)      # the first of each, in the candidates' order
                k = np.empty(len(o), int)
                k[back.ravel()[o]] = np.arange(len(o))
                total, which = self._score(yaw[o], t3[o])
                return total[k[back.ravel()]], which[k[back.ravel()]]
        return self._score(yaw, t3)

    def _score(self, yaw, t3):
        lay, which = self.layouts(yaw, t3[:, [0, 2]])
        return (self.features(yaw, t3) + lay + self.orientation(yaw)
                + self.baseline(t3)), which

    def inliers(self, yaw, t3):
        thr, P = self.p.thr_px, self.P
        if self.n == 0:
            return np.zeros(0, bool), np.zeros(0, bool), np.zeros(0, bool)
        r, front, _, far = _epipolar_terms(P.a, P.b, yaw, t3 / np.linalg.norm(t3), P.pix)
        e_in = ((r < thr) & (front | far))[0]
        tin = []
        for L, rays, into_b in ((P.la, P.b, True), (P.lb, P.a, False)):
            m = np.zeros(self.n, bool)
            i = np.flatnonzero(L.valid & (L.floor | (not self.floor_first)))
            if len(i):
                x = (L.points[i], L.sigma[i], rays[i], into_b)
                m[i] = transfer_residuals(yaw, t3, *x, P.pix) < thr
            tin.append(m)
        return e_in, tin[0], tin[1]

    def refine(self, yaw: float, t3, pair):
        """Robust LM of p = (yaw, tx, ty, tz) on the inliers' epipolar and transfer
        residuals, the layouts' agreeing samples (each wall's samples weighted as ~2
        independent ones) and the priors on the orientation and on ty = dy."""
        P = self.P
        e_in, ta, tb = self.inliers(yaw, t3)
        ia, ib = np.flatnonzero(ta), np.flatnonzero(tb)
        ae, be = P.a[e_in], P.b[e_in]
        lifted = [(P.la.points[ia], P.la.sigma[ia], P.b[ia], True),
                  (P.lb.points[ib], P.lb.sigma[ib], P.a[ib], False)]
        spread = [_spread(yaw, t3, *x, P.pix) for x in lifted]
        lay = (register.residual_terms(self.la[pair[0]], self.lb[pair[1]], yaw, t3[[0, 2]], self.rp)
               if pair[0] >= 0 else None)   # layouts that add nothing do not pull either
        sig_o = np.radians(self.p.orientation_sigma_deg)
        use_o = self.orient is not None and abs(wrap90(self.orient[0] - yaw)) < 3 * sig_o

        def resid(q):
            y, tq = q[:, 0], q[:, 1:4]
            parts = [epipolar_residuals(y, tq, ae, be) / P.pix if len(ae) else np.zeros((len(q), 0))]
            parts += [transfer_residuals(y, tq, *x, P.pix, sp) for x, sp in zip(lifted, spread)
                      if len(x[0])]
            if lay is not None:
                parts.append(lay(y, tq[:, [0, 2]]))
            if use_o:
                parts.append((wrap90(self.orient[0] - y) / sig_o)[:, None])
            parts.append(((tq[:, 1] - self.dy) / (0.02 + 0.03 * np.hypot(tq[:, 0], tq[:, 2])))[:, None])
            return np.concatenate(parts, 1)

        q, cov = levenberg_marquardt(resid, np.array([yaw, *t3]), n_prior=1 + int(use_o),
                                     iters=self.p.refine_iters)
        return q, cov
