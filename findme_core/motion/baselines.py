"""The comparison estimators of planar motion: the paper's (eqs. 5-8) and a lifted-points
baseline. Both use only the matches lifted to 3D in both photos, projected on the floor
(x, z of each photo's level frame, metres); see ``motion`` for the default estimator.
"""

from __future__ import annotations

import numpy as np

from findme_core.errors import MotionError
from findme_core.motion.model import (MotionInputs, MotionParams, PlanarMotion, motion_result,
                                      no_common_view)
from findme_core.geometry.planar import _kabsch_pairs, _rot2, kabsch_2d
from findme_core.geometry.robust import msac, samples


def paper_estimate(P: MotionInputs, inl) -> PlanarMotion:
    """Eqs. 5-8 on the verified matches lifted in both photos (floor projection x, z)."""
    idx = np.flatnonzero(inl & P.la.valid & P.lb.valid)
    if len(idx) == 0:
        raise MotionError("no verified match has a 3D point in both photos (floor or chosen "
                          "wall), so the paper's estimator has nothing to average")
    A, B = P.la.points[idx][:, [0, 2]], P.lb.points[idx][:, [0, 2]]
    w = 2.0 / (A[:, 1] + B[:, 1])                                   # 1 / Z
    d = np.angle(np.exp(1j * (np.arctan2(A[:, 0], A[:, 1]) - np.arctan2(B[:, 0], B[:, 1]))))
    yaw = float(np.sum(w * d) / np.sum(w))                          # eq. 5
    T = A - _rot2(yaw, B)
    t = w @ T / np.sum(w)                                           # eqs. 6-8
    var = lambda x, m: np.sum(w * (x - m) ** 2) * np.sum(w ** 2) / np.sum(w) ** 3  # noqa: E731
    cov = np.diag([var(d, yaw), var(T[:, 0], t[0]), var(T[:, 1], t[1])])
    return motion_result([yaw, *t], P.dy, cov, np.isin(np.arange(len(P.a)), idx), len(idx), "paper")


def lifted_estimate(P: MotionInputs, params: MotionParams, rng) -> PlanarMotion:
    """2-point RANSAC + weighted Kabsch on the matches lifted in both photos, projected on
    the floor; inliers within 3 sigma (both points' sigmas combined, at least 5 cm)."""
    idx = np.flatnonzero(P.la.valid & P.lb.valid)
    if len(idx) < 2:
        raise MotionError(f"only {len(idx)} matches have a 3D point in both photos (floor or "
                          "chosen wall); the lifted estimator needs 2")
    A, B = P.la.points[idx][:, [0, 2]], P.lb.points[idx][:, [0, 2]]
    sig = np.maximum(np.hypot(P.la.sigma[idx], P.lb.sigma[idx]), 0.05)
    res = lambda yaw, t: np.linalg.norm(A - _rot2(yaw, B) - t, axis=-1) / sig  # noqa: E731
    yaw, t = _kabsch_pairs(A, B, samples(rng, len(idx), 2, params.max_iters))
    i = int(np.argmax(msac(res(yaw[:, None], t[:, None]), 3.0)))
    best = (float(yaw[i]), t[i])
    for _ in range(4):
        ok = res(*best) < 3.0
        if ok.sum() < 2:
            raise no_common_view(int(ok.sum()), len(idx))
        best = kabsch_2d(A[ok], B[ok], 1.0 / sig[ok] ** 2)
    # covariance of (yaw, tx, tz) from the Jacobian of the weighted 2-D residuals
    c, s, Bo = np.cos(best[0]), np.sin(best[0]), B[ok]
    J = np.zeros((2 * len(Bo), 3))
    J[0::2, 0], J[1::2, 0] = -s * Bo[:, 0] + c * Bo[:, 1], -c * Bo[:, 0] - s * Bo[:, 1]
    J[0::2, 1], J[1::2, 2] = 1.0, 1.0
    W = np.repeat(1.0 / sig[ok] ** 2, 2)
    chi = np.sum(res(*best)[ok] ** 2) / max(2 * len(Bo) - 3, 1)
    cov = np.linalg.pinv(J.T @ (W[:, None] * J)) * max(chi, 1.0)
    return motion_result([best[0], *best[1]], P.dy, cov, np.isin(np.arange(len(P.a)), idx[ok]),
                   int(ok.sum()), "lifted")
