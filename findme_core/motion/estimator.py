"""The default motion estimator (``findme``): 3-DOF planar registration of two photos by
their room layouts and their feature matches together (see ``methods`` for the method and the
conventions: the pose of camera B in A's level frame, X_A = R_y(yaw) X_B + t, t = (x, dy, z)
metres, yaw radians > 0 when B is turned right of A).

``Registration(...).run()``: yaw candidates (room orientations, the free epipolar RANSAC,
wall pairs), per yaw the baseline directions the matches agree on and the translations the
walls fix, all scored by matches + layouts + orientations + a baseline prior; the best
distinct ones refined by robust Levenberg-Marquardt, ranked; close seconds are alternatives.
Pure numpy; seeded randomness.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from findme_core.errors import MotionError
from findme_core.geometry import ties
from findme_core.geometry.planar import bearings, rot_y, wrap
from findme_core.motion import one_sided, photometric, register
from findme_core.motion.alternatives import (along, as_scored, distinct, distinct_top,
                                              looks_more_alike, more_agree, same, spread_over,
                                              turns)
from findme_core.motion.feature_motion import (_epipolar_ransac, _inflate, _lift_order,
                                               _model_error, check_matches, local_optimisation)
from findme_core.motion.fit import (Fit, Turned, YawScale, common_depth_sigma, known_yaw_score,
                                    scene_depth)
from findme_core.motion.model import (MotionInputs, MotionParams, PlanarMotion, check_position,
                                     motion_result)


class Registration:
    """One run of the ``findme`` estimator (see the module docstring); arguments as
    ``methods.estimate``."""

    def __init__(self, matches, cam_a, cam_b, h_a, h_b, lift_a, lift_b, layouts, orientations,
                 params: MotionParams, copies: int = 0, surfaces=(None, None)):
        self.p, self.m, self.n, self.copies = params, matches, len(matches), copies
        self.surfaces = surfaces
        self.trace = None   # (yaws, candidate yaws (C,), t (C, 3), scores (C,)) once scored
        self.feats = self.n >= params.min_matches
        if self.feats:
            check_matches(matches, params)       # identical photos: an error whatever else
        self.a, self.b = bearings(cam_a, matches.ua), bearings(cam_b, matches.ub)
        self.pix = 1.0 / np.sqrt(cam_a.fx * cam_b.fx)
        self.turned = Turned(self.a, self.b, self.pix)   # per-yaw terms, shared with the Fit
        self.planar, self.dy, self.h = abs(h_a - h_b) < 1e-6, float(h_a - h_b), (h_a, h_b)
        self.lifts = (lift_a, lift_b)
        self.la = list(layouts[0])[:params.max_layouts]
        self.lb = list(layouts[1])[:params.max_layouts]
        oa, ob = orientations
        self.orient = (None if oa is None or ob is None
                       or min(oa.support, ob.support) < params.min_orientation_support
                       else (oa.angle - ob.angle, min(oa.support, ob.support)))
        self.rng = np.random.default_rng(params.seed)
        self.normal = None        # (floor normal in A, yaw) when the features correct gravity
        self.depth = None         # the scene's depth scale (``fit.scene_depth``), metres
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
                y, t, e = _epipolar_ransac(self.a, self.b, self.planar, self.pix,
                                           replace(self.p, max_iters=self.p.free_iters), self.rng)
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
        a, p = self.a, self.p
        Rb, m, ab, far = self.turned(yaw)
        seeds = self.seeds   # the directions of the most distinctive matches are tried
        T = np.column_stack([m[seeds, 2], np.zeros(len(seeds)), -m[seeds, 0]])
        T /= np.maximum(np.linalg.norm(T, axis=1, keepdims=True), 1e-12)
        T = np.vstack([T, -T])
        score, inl = known_yaw_score(a, Rb, m, T, self.pix, p.thr_px, ab, far)
        keep, order = [], ties.order(score)   # directions that score alike: seed order
        floor = max(2.0, 0.3 * score[order[0]])
        for i in order:
            if score[i] < floor or len(keep) == 3:
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
        best = per_yaw[ties.argmax([d[2][0] if len(d[2]) else -1.0 for d in per_yaw])]
        if len(best[2]):
            first |= best[1][0]
        self.P = self._lift(first)
        self.depth = scene_depth(self.P, self.la, self.lb)
        self.fit = Fit(self.P, self.la, self.lb, self.orient, self.depth, self.p, self.rp,
                       self.turned)
        uses = (self.P.usable(False), self.P.usable(True))   # floor points first
        cy, ct = [], []

        def add(yaw, t):   # (N, 2) x, z (dy: h_A - h_B) or (N, 3)
            t = np.asarray(t, float)
            t = self._t3(t.reshape(-1, 2)) if t.shape[-1] == 2 else t.reshape(-1, 3)
            cy.extend([yaw] * len(t))
            ct.append(t)

        dirs = [(y, T, inl, False) for y, (T, inl, _) in zip(yaws, per_yaw)]
        if free is not None:   # with equal heights (assumed, not measured), its direction
            # may rise or fall: uneven ground, a hand-held phone
            dirs.append((free[0], free[1][None], free[2][None], self.planar))
        walls = self._layout_pairs()
        scale = YawScale(self.P, self.turned)   # ``_scale`` with its per-yaw terms kept
        wall_only = (uses[1][0] & ~uses[0][0]) | (uses[1][1] & ~uses[0][1])
        for y, T, inl, free_dir in dirs:
            for t, e in zip(T, inl):
                for k, use in enumerate(uses):
                    if k == 0 or (e & wall_only).any():
                        s = scale(y, t, e, use)
                    # else: no wall point among the inliers: the same points, the same s
                    if s is not None:   # the direction's own elevation, and dy = h_A - h_B
                        add(y, s * t[[0, 2]])
                        if free_dir:
                            add(y, s * t)
            d2 = T[:, [0, 2]] / np.maximum(np.linalg.norm(T[:, [0, 2]], axis=1, keepdims=True), 1e-12)
            for pair in walls:
                add(y, pair(y, d2))
        # matches lifted in one photo only, placed in the other by their height
        corr = one_sided.correspondences(self.P, self.p.lift_min_elev_deg)
        for y in yaws:
            add(y, one_sided.at_yaw(corr, y))
        for pair in walls:   # the walls alone (one wall: one direction)
            for y in yaws:
                add(y, pair(y, None, single=not self.feats))
        if not cy:
            return np.zeros(0), np.zeros((0, 3))
        return np.array(cy), np.vstack(ct)

    def _layout_pairs(self):
        """The layout pairs that propose translations (``register.Translations``): every
        pair of the candidate hypotheses, up to ``gen_layouts`` of each photo (the chosen
        ones first)."""
        k = self.p.gen_layouts
        return [register.Translations(la, lb, self.rp)
                for la in self.la[:k] for lb in self.lb[:k]]

    def _t3(self, t2):
        t3 = np.empty((len(t2), 3))   # filled: ~50 calls a pair, mostly of a few rows
        t3[:, 0], t3[:, 1], t3[:, 2] = t2[:, 0], self.dy, t2[:, 1]
        return t3

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
        ok = np.isfinite(ct).all(1) & (np.hypot(ct[:, 0], ct[:, 2]) < self.p.max_baseline_m)
        cy, ct = cy[ok], ct[ok]
        if len(cy) == 0:   # no candidate, or none nearer than ``max_baseline_m``
            raise self._refusal(0)
        total, which = self.fit.score(cy, ct)
        # the photos' appearance where each sees the other's surfaces: the best candidates
        top_k = distinct_top(cy, ct, total, self.p.photometric_top)
        total[top_k] += self._photometric(cy[top_k], ct[top_k])[0]
        self.trace = (yaws, cy, ct, total)   # what was weighed (``tools/motion_pairs.py``)
        results, top = [], float(total.max())
        # best first; motions that score alike (a symmetric room: the same walls turned
        # half round) in the candidates' order, the same on every machine
        for i in ties.order(total):
            if len(results) == self.p.refine_top or (
                    results and total[i] < self.p.alternative_ratio * top):
                break
            if any(same(cy[i], ct[i, [0, 2]], r[0][0], r[0][[1, 3]]) for r in results):
                continue
            results.append(self._refined(cy[i], ct[i], which[i]))
        results = [results[i] for i in ties.order(np.array([r[2] for r in results]))]
        # the best motion the evidence determines (one with too few matches and walls along
        # one direction only is a family of motions, not an answer: the next one may be)
        motions = [self._result(*r) for r in results]
        out, k = distinct(motions, [self._undetermined(o, r[3])
                                    for o, r in zip(motions, results)])
        out = [(motions[i], results[i][3]) for i in out]
        best = out[k][0]
        alts = tuple(o for o, _ in out[:k] + out[k + 1:]
                     if o.score >= self.p.alternative_ratio * best.score)
        alts += self._rivals(best, alts, cy, ct, total, which)
        alts += tuple(as_scored(best, cy[i], ct[i], s, *self._evidence(cy[i], ct[i], which[i]))
                      for i, s in along(best, alts, cy, ct, self.fit.scale_score,
                                        self.p.scale_ratio, self.p.refine_top))
        return spread_over(replace(best, alternatives=alts))

    def _rivals(self, best, alts, cy, ct, total, which) -> tuple:
        """The rivals of ``best`` (``alternatives.turns``: in a symmetric room its other quarter
        turns and half turn, best-scoring first) the photos do not prefer it to (``_rival``),
        each tested on its own: one they rule out (a half turn few matches agree with) hid
        the next (the quarter turn as many agree with: dev pair zpl_r06_p10_p11_t2, a phone's
        gravity, 2026-12-02: 89 deg off at +-1.4 deg with only the half turn tested)."""
        out = ()
        for i in turns(cy, total, best.yaw, np.radians(self.p.rival_sep_deg)):
            out += self._rival(i, best, alts + out, cy, ct, which)
        return out

    def _rival(self, i: int, best, alts, cy, ct, which) -> tuple:
        """Candidate ``i``, a motion turned away from ``best``, refined, when the photos do
        not prefer ``best`` to it: () or (it,). They do not when the counts of
        agreeing matches differ by at most their standard error (sqrt of their sum: counts
        of chance agreements scatter as Poisson's) and the appearance correlations by at
        most theirs. Only the layouts and room orientations chose ``best`` then, and they
        look alike turned a quarter or half turn in a symmetric room. Dev pairs
        (2026-11-30): all 5 answers off by over 20 deg had one; the counts compared as
        "at least as many" (until 2026-12-01) left out zpl_r06_p10_p11_t1's, 8 matches
        against the answer's 11, its answer 90 deg off at +-0.8 deg."""
        sep = np.radians(self.p.rival_sep_deg)
        if any(abs(wrap(a.yaw - cy[i])) <= sep for a in alts):
            return ()
        n_i, n_b = self._support(cy[i], ct[i]), self._support(best.yaw, (best.x, best.dy, best.z))
        if more_agree(n_b, n_i):
            return ()
        o = self._result(*self._refined(cy[i], ct[i], which[i]))
        if looks_more_alike(best.appearance, o.appearance) or same(
                o.yaw, (o.x, o.z), best.yaw, (best.x, best.z)):
            return ()
        return (o,)

    def _refined(self, yaw, t3, pair):
        """(q = (yaw, x, dy, z), its covariance, score, layout pair, appearance) of one
        candidate refined (``Fit.refine``) and scored again with its appearance."""
        q, cov = self.fit.refine(yaw, t3, pair)
        s, w = self.fit.score(q[0], q[1:4])
        ph, corr, n = self._photometric(q[:1], q[None, 1:4])
        return q, cov, float(s[0] + ph[0]), w[0], (float(corr[0]), int(n[0]))

    def _support(self, yaw, t3) -> int:
        """Matches consistent with one motion: epipolar, or transferred from either photo's
        lifted points (``Fit.inliers``)."""
        e_in, ta, tb = self.fit.inliers(yaw, np.asarray(t3, float))
        return int((e_in | ta | tb).sum())

    def _photometric(self, yaw, t3):
        """(C,) score of C motions by the photos' appearance (``photometric``: the
        summed products of the normalised images over the samples each photo sees of the
        other's surfaces, times ``photometric_weight``), (C,) their correlation and (C,)
        sample counts."""
        corr, n = photometric.agreement(*self.surfaces, yaw, t3)
        return self.p.photometric_weight * corr * n, corr, n

    def _undetermined(self, m: PlanarMotion, pair) -> MotionError | None:
        """Why the evidence does not fix the motion ``m`` (its layout pair ``pair``), or None."""
        try:
            if m.n_inliers < self.p.min_inliers:
                if m.layout is None or m.layout.samples < self.p.min_layout_samples:
                    raise self._refusal(m.n_inliers)
                m.layout.check_fixes_translation(self.la[max(pair[0], 0)])
            check_position(m, self.h[0])
        except MotionError as e:
            return e
        return None

    def _evidence(self, yaw, t3, pair):
        """(agreeing matches (M,), of them lifted in A, in B, the layouts' Agreement | None)."""
        e_in, ta, tb = self.fit.inliers(yaw, t3)
        i, j = max(pair[0], 0), max(pair[1], 0)
        return e_in | ta | tb, ta, tb, (register.agreement(
            self.la[i], self.lb[j], yaw, t3[[0, 2]], self.rp) if self.la and self.lb else None)

    def _result(self, q, cov, score, pair, appearance) -> PlanarMotion:
        inl, ta, tb, lay = self._evidence(q[0], q[1:4], pair)
        r = motion_result(q[[0, 1, 3]], q[2], cov[np.ix_([0, 1, 3], [0, 1, 3])], inl,
                          int(ta.sum() + tb.sum()), "findme")
        depth = common_depth_sigma([(L.points[m], L.sigma[m])
                                    for L, m in ((self.P.la, ta), (self.P.lb, tb))])
        return _model_error(replace(r, layout=lay, score=score, appearance=appearance), self.p,
                            depth)

    def _refusal(self, k: int) -> MotionError:
        walls = ("the photos' boundaries share no wall" if self.la and self.lb else
                 "a photo has no boundary hypothesis, so its walls are unknown")
        if not self.feats:
            more = f", plus {self.copies} copies of them" if self.copies else ""
            return MotionError(f"only {self.n} distinct feature matches between the photos "
                               f"({self.m.n_a} and {self.m.n_b} keypoints{more}; need "
                               f"{self.p.min_matches}) and "
                               f"{walls}: they show too little in common")
        return MotionError(f"the photos have no common view: only {k} of {self.n} distinct "
                           f"feature matches agree on one camera motion and {walls}")
