"""Robust estimation primitives shared by the motion estimators: MSAC scoring, seeded
minimal-sample draws and a robust (Cauchy-weighted) Levenberg-Marquardt.

Pure numpy; the callers give residual functions in their own units (pixels over sigma).
"""

from __future__ import annotations

import numpy as np


def msac(r, thr):
    """MSAC score per row (truncated quadratic): sum of max(0, 1 - (r / thr)^2)."""
    return np.sum(np.maximum(0.0, 1.0 - (r / thr) ** 2), axis=-1)


def samples(rng, n: int, k: int, count: int) -> np.ndarray:
    """(<= count, k) index samples without repetition inside a sample."""
    s = rng.integers(0, n, (count, k))
    return s[np.all(np.diff(np.sort(s, 1), axis=1) > 0, axis=1)]


def levenberg_marquardt(resid, p, n_prior: int = 0, iters: int = 8, c: float = 2.5):
    """LM with a forward-difference Jacobian (``resid`` maps (C, k) parameters to (C, R)
    residuals, each row from its own parameters alone: a step is evaluated with its Jacobian
    in one call); Cauchy loss (scale c) on all residuals but the last ``n_prior`` (Gaussian
    priors). Returns the parameters and their covariance, inflated by the robust chi^2 per
    degree of freedom when > 1."""
    k, h = len(p), 1e-7

    def weights(r):
        w = 1.0 / (1.0 + (r / c) ** 2)
        w[len(r) - n_prior:] = 1.0
        return w

    def cost(r):
        d, q = r[:len(r) - n_prior], r[len(r) - n_prior:]
        return float(c * c * np.sum(np.log1p((d / c) ** 2)) + q @ q)

    def eval_jac(p):
        R = resid(np.vstack([p, p + h * np.eye(k)]))
        return R[0], (R[1:] - R[0]).T / h

    lam, (r, J) = 1e-3, eval_jac(p)
    for _ in range(iters):
        w = weights(r)
        H, g = J.T @ (w[:, None] * J), J.T @ (w * r)
        now = cost(r)
        while lam < 1e8:
            dp = -np.linalg.solve(H + lam * np.diag(np.diag(H) + 1e-12), g)
            # a step is tried with its Jacobian (one call of ``resid``, rows independent):
            # nearly all steps are taken
            r1, J1 = eval_jac(p + dp)
            if cost(r1) < now:
                p, lam, r, J = p + dp, lam * 0.3, r1, J1
                break
            lam *= 10.0
        if lam >= 1e8 or np.max(np.abs(dp)) < 1e-8:
            break
    w = weights(r)
    chi = float(np.sum(w * r * r)) / max(len(r) - k, 1)
    return p, np.linalg.pinv(J.T @ (w[:, None] * J)) * max(chi, 1.0)
