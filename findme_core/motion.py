"""Planar camera motion between two photos (paper step 5): the default estimator, which
registers the two photos' room layouts together with their feature matches, and dispatch.

Frames and units (DESIGN.md): each photo has a level frame (y down along gravity, z the
optical axis projected on the horizontal plane, x right). The motion of a pair (A, B) is
the pose of camera B in A's level frame: X_A = R_y(yaw) X_B + t for level-frame points,
t = (x, dy, z) metres, yaw radians (> 0: B turned right of A); dy is expected near
h_A - h_B. Per match i: unit level bearings a_i (A), b_i (B) and, where a photo's chosen
hypothesis gives one, its lifted 3D point (paper eqs. 2-4). Per photo: the layouts of its
candidate hypotheses (``layout.Layout``, the chosen one first) and the room's orientation
from its lines (``layout.Orientation``).

Estimators (``METHODS``):

* ``findme`` (default): (1) yaws: the two photos' room orientations (their difference
  modulo 90 deg: four candidates in a box room), the feature matches' free gravity-aware
  epipolar RANSAC, and walls of B turned onto walls of A. (2) Per yaw, the baseline
  directions the matches agree on (one match fixes the direction of a known-yaw motion:
  t . (R_y b x a) = 0), each scaled by the lifted points' consensus, by a wall of B put on
  a wall of A, and by a 1-D search of the layouts' agreement; and the translations two
  non-parallel walls or a corner fix on their own (textureless walls: no match at all).
  (3) Every candidate is scored by the matches (MSAC of epipolar and lifted transfer
  residuals, pixels), the layouts (``register``: boundary samples of each photo on the
  other's walls, minus samples on floor the other photo sees) and the orientations; the
  best distinct ones are refined by robust Levenberg-Marquardt of (yaw, x, dy, z) on all
  three, and ranked. Motions the evidence allows nearly as well (a symmetric room) are the
  answer's ``alternatives``.
* ``features`` (``motion_features``): the matches alone (the default before layouts).
* ``lifted``, ``paper`` (``motion_baselines``): 2-point Kabsch on lifted matches; the
  paper's eqs. 5-8 on the ``features`` RANSAC's verified matches.

Every estimate carries its inliers and 1-sigma uncertainties (covariance of the fit, inflated
by the robust chi^2 per degree of freedom, plus model errors). Degenerate input raises
``MotionError`` naming the cause. Pure: numpy in, numbers out; seeded randomness.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from . import register
from .camera import Camera
from .errors import InputError, MotionError
from .features import Matches
from .layout import Orientation
from .motion_features import (Lifter, _epipolar_ransac, _inflate, _lift_order, _model_error,
                              _scale, check_matches, features_estimate, local_optimisation)
from .motion_model import MotionInputs, MotionParams, PlanarMotion, motion_result  # noqa: F401
from .planar import (_epipolar_terms, _rotate, _spread, bearings, epipolar_residuals, rot_y,
                     transfer_residuals)
from .robust import levenberg_marquardt, msac

METHODS = ("findme", "features", "lifted", "paper")


def estimate(matches: Matches, cam_a: Camera, cam_b: Camera, h_a: float, h_b: float,
             lift_a: Lifter | None, lift_b: Lifter | None, method: str = "findme",
             params: MotionParams = MotionParams(), *, layouts=((), ()),
             orientations=(None, None)) -> PlanarMotion:
    """Planar motion of B in A's level frame.

    Args:
        matches: putative matches (pixels of A and B); may be empty for ``findme``.
        cam_a, cam_b: intrinsics and gravity of each photo.
        h_a, h_b: camera heights above the floor, metres.
        lift_a, lift_b: match indices -> ``Lifted`` of all matches (3D where computed), e.g.
            ``lambda i: features.lift(scene_a, matches.ua, i)``; None for a photo without
            a usable hypothesis. At most ``params.max_lift`` matches are asked for.
        method: one of ``METHODS``.
        layouts: (A's, B's) sequences of ``layout.Layout`` of candidate hypotheses, the
            chosen one first (``findme`` only).
        orientations: (A's, B's) ``layout.Orientation`` or None (``findme`` only).

    Raises:
        MotionError: too few matches and no common wall, identical photos, no common view,
            only parallel walls in common and no match, no 3D for scale.
    """
    if method not in METHODS:
        raise InputError(f"unknown motion method {method!r}; choose one of {', '.join(METHODS)}")
    if method != "findme":
        return features_estimate(matches, cam_a, cam_b, h_a, h_b, lift_a, lift_b, method, params)
    return _Registration(matches, cam_a, cam_b, h_a, h_b, lift_a, lift_b, layouts,
                         orientations, params).run()


def _wrap90(x):
    """Angle difference modulo a quarter turn, in [-pi/4, pi/4)."""
    return (np.asarray(x) + np.pi / 4) % (np.pi / 2) - np.pi / 4


class _Registration:
    """One run of the ``findme`` estimator (see the module docstring)."""

    def __init__(self, matches, cam_a, cam_b, h_a, h_b, lift_a, lift_b, layouts, orientations,
                 params: MotionParams):
        self.p, self.m, self.n = params, matches, len(matches)
        self.feats = self.n >= params.min_matches
        if self.feats:
            check_matches(matches, params)       # identical photos: an error whatever else
        self.a, self.b = bearings(cam_a, matches.ua), bearings(cam_b, matches.ub)
        self.pix = 1.0 / np.sqrt(cam_a.fx * cam_b.fx)
        self.planar, self.dy, self.h = abs(h_a - h_b) < 1e-6, float(h_a - h_b), (h_a, h_b)
        self.lifts = (lift_a, lift_b)
        self.la = list(layouts[0])[:params.max_layouts]
        self.lb = list(layouts[1])[:params.max_layouts]
        oa, ob = orientations
        self.orient = (None if oa is None or ob is None
                       or min(oa.support, ob.support) < params.min_orientation_support
                       else (oa.angle - ob.angle, min(oa.support, ob.support)))
        self.rng = np.random.default_rng(params.seed)
        self.floor_first = None   # decided on the first candidates scored
        self.normal = None        # (floor normal in A, yaw) when the features correct gravity
        self.seeds = np.argsort(matches.ratio, kind="stable")[:params.max_direction_seeds]
        self.rp = register.RegisterParams(weight=params.layout_weight,
                                          violation=params.layout_violation)

    # ------------------------------------------------------------------ candidates
    def _yaws(self):
        yaws, free = [], None
        if self.orient is not None:
            yaws += [self.orient[0] + k * np.pi / 2 for k in range(4)]
        if self.feats:
            try:
                y, t, e = _epipolar_ransac(self.a, self.b, self.planar, self.pix, self.p, self.rng)
                y, t, e, sig_elev = local_optimisation(self.a, self.b, y, t, e, self.planar,
                                                       self.pix, self.p)
                yaws.append(y)
                free = (y, t, e)
                if self.planar and abs(t[1]) > 3.0 * np.sin(sig_elev):
                    # moved parallel to the floor: the floor normal is orthogonal to t, and
                    # floor points are lifted on that corrected floor (``features``)
                    normal = np.array([0.0, 1.0, 0.0]) - t[1] * t
                    self.normal = (normal / np.linalg.norm(normal), y)
            except MotionError:
                pass
        if self.la and self.lb:   # the longest wall pairs first
            yaws += list(register.wall_yaws(self.la[0], self.lb[0], self.rp)[:self.p.max_wall_yaws])
        out = []
        for y in np.angle(np.exp(1j * np.array(yaws, float))):
            if all(abs(np.angle(np.exp(1j * (y - z)))) > np.radians(2.0) for z in out):
                out.append(float(y))
        return out, free

    def _directions(self, yaw: float):
        """Unit horizontal baseline directions (K, 3) the matches agree on at this yaw, with
        their epipolar inliers (K, M): one match fixes the direction (t . (R b x a) = 0);
        all of them are scored at once (matrix products) and the best distinct ones kept."""
        a, Rb, p = self.a, _rotate(np.array([yaw]), self.b)[0], self.p
        m = np.cross(Rb, a)
        seeds = self.seeds   # the directions of the most distinctive matches are tried
        T = np.column_stack([m[seeds, 2], np.zeros(len(seeds)), -m[seeds, 0]])
        T /= np.maximum(np.linalg.norm(T, axis=1, keepdims=True), 1e-12)
        num, at, bt = T @ m.T, T @ a.T, T @ Rb.T
        r = np.abs(num) / np.sqrt(np.maximum(0.5 * (2.0 - at ** 2 - bt ** 2), 1e-12)) / self.pix
        ab = np.sum(a * Rb, 1)
        det = np.maximum(1.0 - ab * ab, 1e-12)
        la, lb = (at - ab * bt) / det, (ab * at - bt) / det
        far = np.linalg.norm(m, axis=1) / self.pix < 1.0
        ok = r < p.thr_px
        fwd, bwd = ok & (far | ((la > 0) & (lb > 0))), ok & (far | ((la < 0) & (lb < 0)))
        T, inl = np.vstack([T, -T]), np.vstack([fwd, bwd])
        score = msac(np.where(inl, np.vstack([r, r]), p.thr_px), p.thr_px)
        keep = []
        for i in np.argsort(-score):
            if score[i] < max(2.0, 0.3 * score[np.argsort(-score)[0]]) or len(keep) == 3:
                break
            if all(T[i] @ T[j] < np.cos(np.radians(3.0)) for j in keep):
                keep.append(i)
        return T[keep], inl[keep], score[keep]

    def _lift(self, first):
        sel = _lift_order(self.a, self.m.ratio, first, self.p.max_lift)
        na = nb = None
        if self.normal is not None:
            na, nb = self.normal[0], rot_y(self.normal[1]).T @ self.normal[0]
        return MotionInputs(self.a, self.b,
                            _inflate(self.lifts[0], sel, self.n, self.h[0], self.p, na, self.a),
                            _inflate(self.lifts[1], sel, self.n, self.h[1], self.p, nb, self.b),
                            self.dy, self.h[0], self.pix)

    def _candidates(self, yaws, free):
        none = (np.zeros((0, 3)), np.zeros((0, self.n), bool), np.zeros(0))
        per_yaw = [self._directions(y) if self.feats else none for y in yaws]
        # lift the inliers of the free RANSAC and of the best direction at any yaw first
        first = np.zeros(self.n, bool) if free is None else free[2].copy()
        best = max(per_yaw, key=lambda d: d[2][0] if len(d[2]) else -1.0)
        if len(best[2]):
            first |= best[1][0]
        self.P = self._lift(first)
        uses = (self.P.usable(False), self.P.usable(True))   # floor points first
        cy, ct = [], []

        def add(yaw, t2):
            t2 = np.asarray(t2, float).reshape(-1, 2)
            cy.extend([yaw] * len(t2))
            ct.append(t2)

        dirs = [(y, T, inl) for y, (T, inl, _) in zip(yaws, per_yaw)]
        if free is not None:
            dirs.append((free[0], free[1][None], free[2][None]))
        for y, T, inl in dirs:
            for t, e in zip(T, inl):
                for use in uses:
                    s = _scale(self.P, y, t, e, use)
                    if s is not None:
                        add(y, s * t[[0, 2]])
            d2 = T[:, [0, 2]] / np.maximum(np.linalg.norm(T[:, [0, 2]], axis=1, keepdims=True), 1e-12)
            for la in self.la[:1]:
                for lb in self.lb[:1]:
                    add(y, register.translations(la, lb, y, d2, self.rp))
        if self.la and self.lb:
            for y in yaws:
                add(y, register.translations(self.la[0], self.lb[0], y, None, self.rp))
        if not cy:
            return np.zeros(0), np.zeros((0, 2))
        return np.array(cy), np.vstack(ct)

    # ------------------------------------------------------------------ scoring
    def _t3(self, t2):
        return np.column_stack([t2[:, 0], np.full(len(t2), self.dy), t2[:, 1]])

    def _feature_score(self, yaw, t3):
        """(C,) MSAC of the epipolar residuals of all matches and the transfer residuals of
        the lifted points (pixels over their spread, the spread capped at 3): floor points
        only once some motion has ``min_floor`` of them agreeing (``self.floor_first``: a
        wall point is right only when its wall is), else wall points too."""
        if self.n == 0:
            return np.zeros(len(yaw))
        thr, P = self.p.thr_px, self.P
        r, front, _, far = _epipolar_terms(P.a, P.b, yaw, t3 / np.linalg.norm(t3, axis=1,
                                                                             keepdims=True), P.pix)
        score = msac(np.where((r < thr) & (front | far), r, thr), thr)
        floor, wall, n_floor = np.zeros(len(yaw)), np.zeros(len(yaw)), np.zeros(len(yaw))
        for L, rays, into_b in ((P.la, P.b, True), (P.lb, P.a, False)):
            i = np.flatnonzero(L.valid)
            if len(i):
                x = (L.points[i], L.sigma[i], rays[i], into_b)
                sp = np.minimum(_spread(yaw, t3, *x, P.pix), 3.0)
                rt = transfer_residuals(yaw, t3, *x, P.pix, sp)
                f = L.floor[i]
                floor += msac(rt[:, f], thr)
                wall += msac(rt[:, ~f], thr)
                n_floor += (rt[:, f] < thr).sum(1)
        if self.floor_first is None:
            self.floor_first = bool(n_floor.max(initial=0) >= self.p.min_floor)
        return score + floor + (0.0 if self.floor_first else wall)

    def _layout_score(self, yaw, t2):
        """(C,) best layout score over the candidate layout pairs (a layout that is not the
        chosen one loses ``rank_penalty`` per step; layouts that disagree add nothing rather
        than count against: a wrong hypothesis must not outvote the matches), and the pair
        (i, j) of each."""
        best, which = np.full(len(yaw), self.p.layout_floor), np.zeros((len(yaw), 2), int)
        for i, la in enumerate(self.la):
            for j, lb in enumerate(self.lb):
                s = register.scores(la, lb, yaw, t2, self.rp) - self.p.rank_penalty * (i + j)
                better = s > best
                best = np.where(better, s, best)
                which[better] = (i, j)
        return best, which

    def _orient_score(self, yaw):
        if self.orient is None:
            return np.zeros(len(yaw))
        d = _wrap90(self.orient[0] - yaw) / (3.0 * np.radians(self.p.orientation_sigma_deg))
        return self.p.orientation_weight * self.orient[1] * np.maximum(0.0, 1.0 - d * d)

    def _total(self, yaw, t2):
        yaw = np.atleast_1d(np.asarray(yaw, float))
        t2 = np.atleast_2d(t2)
        lay, which = self._layout_score(yaw, t2)
        return self._feature_score(yaw, self._t3(t2)) + lay + self._orient_score(yaw), which

    # ------------------------------------------------------------------ refinement
    def _inliers(self, yaw, t3):
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

    def _refine(self, yaw: float, t3, pair):
        """Robust LM of p = (yaw, tx, ty, tz) on the inliers' epipolar and transfer
        residuals, the layouts' agreeing samples (each wall's samples weighted as ~2
        independent ones) and the priors on the orientation and on ty = dy."""
        P = self.P
        e_in, ta, tb = self._inliers(yaw, t3)
        ia, ib = np.flatnonzero(ta), np.flatnonzero(tb)
        ae, be = P.a[e_in], P.b[e_in]
        lifted = [(P.la.points[ia], P.la.sigma[ia], P.b[ia], True),
                  (P.lb.points[ib], P.lb.sigma[ib], P.a[ib], False)]
        spread = [_spread(yaw, t3, *x, P.pix) for x in lifted]
        lay = (register.residual_terms(self.la[pair[0]], self.lb[pair[1]], yaw, t3[[0, 2]], self.rp)
               if self.la and self.lb else None)
        sig_o = np.radians(self.p.orientation_sigma_deg)
        use_o = self.orient is not None and abs(_wrap90(self.orient[0] - yaw)) < 3 * sig_o

        def resid(q):
            y, tq = q[:, 0], q[:, 1:4]
            parts = [epipolar_residuals(y, tq, ae, be) / P.pix if len(ae) else np.zeros((len(q), 0))]
            parts += [transfer_residuals(y, tq, *x, P.pix, sp) for x, sp in zip(lifted, spread)
                      if len(x[0])]
            if lay is not None:
                parts.append(lay(y, tq[:, [0, 2]]))
            if use_o:
                parts.append((_wrap90(self.orient[0] - y) / sig_o)[:, None])
            parts.append(((tq[:, 1] - self.dy) / (0.02 + 0.03 * np.hypot(tq[:, 0], tq[:, 2])))[:, None])
            return np.concatenate(parts, 1)

        q, cov = levenberg_marquardt(resid, np.array([yaw, *t3]), n_prior=1 + int(use_o))
        return q, cov

    # ------------------------------------------------------------------ answer
    def run(self) -> PlanarMotion:
        yaws, free = self._yaws()
        if not yaws:
            raise self._refusal(0)
        cy, ct = self._candidates(yaws, free)
        if len(cy) == 0 and free is not None:
            raise MotionError("no matched point lies on the floor or on a chosen wall "
                              "consistently with the motion in either photo, and no wall is "
                              "known in both, so the distance between the photos cannot be "
                              "measured")
        if len(cy) == 0:
            raise self._refusal(0)
        ok = np.isfinite(ct).all(1) & (np.linalg.norm(ct, axis=1) < self.p.max_baseline_m)
        cy, ct = cy[ok], ct[ok]
        if len(cy) == 0:
            raise self._refusal(0)
        total, which = self._total(cy, ct)
        results = []
        for i in np.argsort(-total):
            if len(results) == self.p.refine_top:
                break
            if any(self._same(cy[i], ct[i], r[0][0], r[0][[1, 3]]) for r in results):
                continue
            q, cov = self._refine(cy[i], self._t3(ct[i:i + 1])[0], which[i])
            s, w = self._total(q[0], q[[1, 3]])
            results.append((q, cov, float(s[0]), w[0]))
        results.sort(key=lambda r: -r[2])
        out = []
        for r in results:
            o = self._result(*r)
            if not any(self._same(o.yaw, (o.x, o.z), p.yaw, (p.x, p.z)) for p, _ in out):
                out.append((o, r[3]))
        best, pair = out[0]
        if best.n_inliers < self.p.min_inliers:
            if best.layout is None or best.layout.samples < self.p.min_layout_samples:
                raise self._refusal(best.n_inliers)
            self._check_layout_only(best, pair)
        alts = tuple(o for o, _ in out[1:] if o.score >= self.p.alternative_ratio * best.score)
        return replace(best, alternatives=alts)

    def _same(self, y1, t1, y2, t2) -> bool:
        dt = np.hypot(t1[0] - t2[0], t1[1] - t2[1])
        return (abs(np.angle(np.exp(1j * (y1 - y2)))) < np.radians(3.0)
                and dt < 0.1 + 0.1 * np.hypot(*t1[:2]))

    def _result(self, q, cov, score, pair) -> PlanarMotion:
        t3 = q[1:4]
        e_in, ta, tb = self._inliers(q[0], t3)
        lay = (register.agreement(self.la[pair[0]], self.lb[pair[1]], q[0], t3[[0, 2]], self.rp)
               if self.la and self.lb else None)
        r = motion_result(q[[0, 1, 3]], q[2], cov[np.ix_([0, 1, 3], [0, 1, 3])],
                          e_in | ta | tb, int(ta.sum() + tb.sum()), "findme")
        return _model_error(replace(r, layout=lay, score=score), self.p)

    def _refusal(self, k: int) -> MotionError:
        walls = ("the photos' boundaries share no wall" if self.la and self.lb else
                 "a photo has no boundary hypothesis, so its walls are unknown")
        if not self.feats:
            return MotionError(f"only {self.n} feature matches between the photos ({self.m.n_a} "
                               f"and {self.m.n_b} keypoints; need {self.p.min_matches}) and "
                               f"{walls}: they show too little in common")
        return MotionError(f"the photos have no common view: only {k} of {self.n} feature "
                           f"matches agree on one camera motion and {walls}")

    def _check_layout_only(self, m: PlanarMotion, pair) -> None:
        """Without matches, the walls must fix both directions of the translation."""
        lay = m.layout
        if lay.corners:
            return
        la = self.la[pair[0]]
        n = la.normals[[i for i, _ in lay.walls]] if lay.walls else np.zeros((0, 2))
        if len(n) and np.abs(np.cross(n[:, None], n[None])).max() > np.sin(np.radians(30)):
            return
        what = "one wall" if len({i for i, _ in lay.walls}) <= 1 else "only parallel walls"
        raise MotionError(f"the photos share {what} and no feature match agrees: the motion "
                          "along the wall cannot be measured")
