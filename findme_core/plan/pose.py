"""How well a photo's pose on a floor plan is pinned: the 1-sigma of (x, z, yaw) from its
wall samples against the plan's walls.

Frames: the plan's room frame (x, z metres; ``floorplan``); a pose (x, z, yaw) maps a floor
point p of the photo's level frame to q = R(yaw) p + (x, z), R(yaw) = [[c, s], [-s, c]] on
(x, z) (``register.rot2``; yaw > 0 turned right, radians).

Each wall-base sample p_i of the photo (``Layout.points`` of WALL kind) lands at q_i; against
the seen plan wall nearest to it (unit normal n_i, offset d_i: n . q = d) its residual is
r_i = n_i . q_i - d_i. Linearised in (x, z, yaw):

    J_i = [n_ix, n_iz, n_i . dR/dyaw p_i],   dR/dyaw p = (-s p_x + c p_z, -c p_x - s p_z)

and the Gauss-Newton covariance is sigma_r^2 (J^T J)^-1 with sigma_r the rms residual,
floored at ``floor_m`` (boundary noise that agreement alone cannot show). Samples along one
wall are not independent (they share the error of the wall's line), so the covariance is
inflated by N / N_eff with N_eff = 2 per wall the photo sees (its offset and direction).

Pure numpy; no I/O.
"""

from __future__ import annotations

import numpy as np

from findme_core.geometry import ties
from findme_core.motion import register
from findme_core.plan.floorplan import Plan
from findme_core.single.layout import Layout
from findme_core.single.search import SegKind


def covariance(plan: Plan, L: Layout, pose, gate_m: float = 0.15, floor_m: float = 0.02,
               min_samples: int = 6, max_cond: float = 1e8) -> np.ndarray | None:
    """(3, 3) covariance of a photo's pose (x, z metres; yaw radians) on ``plan``, or None
    when its wall samples do not pin all three (fewer than ``min_samples`` within
    ``gate_m`` of a seen plan wall, or only parallel walls: a singular J^T J)."""
    seen = np.array([w.seen for w in plan.walls], bool)
    if L is None or not seen.any() or not np.all(np.isfinite(pose)):
        return None
    p = L.points[(L.kind == SegKind.WALL) & np.isfinite(L.range)]
    if len(p) < min_samples:
        return None
    yaw = float(pose[2])
    q = register.rot2(np.array([yaw]), p)[0] + np.asarray(pose[:2], float)
    a = np.array([w.a for w in plan.walls])[seen]
    b = np.array([w.b for w in plan.walls])[seen]
    d = b - a
    t = np.clip(np.einsum("sij,ij->si", q[:, None] - a[None], d)
                / np.maximum(np.einsum("ij,ij->i", d, d), 1e-12), 0, 1)
    dist = np.linalg.norm(q[:, None] - (a[None] + t[..., None] * d[None]), axis=2)
    k = ties.argmin(dist, axis=1)   # a sample at a corner: the first wall
    ok = dist[np.arange(len(q)), k] < gate_m
    if ok.sum() < min_samples:
        return None
    p, q, k = p[ok], q[ok], k[ok]
    n = np.column_stack([-d[k, 1], d[k, 0]]) / np.linalg.norm(d[k], axis=1, keepdims=True)
    r = np.einsum("ij,ij->i", n, q - a[k])
    c, s = np.cos(yaw), np.sin(yaw)
    dq = np.column_stack([-s * p[:, 0] + c * p[:, 1], -c * p[:, 0] - s * p[:, 1]])
    J = np.column_stack([n, np.einsum("ij,ij->i", n, dq)])
    JtJ = J.T @ J
    if np.linalg.cond(JtJ) > max_cond:
        return None
    sigma_r = max(float(np.sqrt(np.mean(r ** 2))), floor_m)
    inflate = len(r) / (2.0 * len(np.unique(k)))
    return sigma_r ** 2 * max(inflate, 1.0) * np.linalg.inv(JtJ)


def spread(alternatives, weight: float = 1.0) -> np.ndarray:
    """(3,) 1-sigma (x, z metres; yaw radians) a placed pose gains from the poses its
    photos' evidence scores nearly as well (its block's ``fuse.Placement.alternatives``:
    ((offset (3,), score ratio), ...)): the spread about it of the mixture of it (weight 1)
    and them (weight ``weight`` x the ratio, at most 1), sqrt(sum_k w_k d_k^2) per axis with
    w normalised over all, as ``motion.alternatives.spread_over`` widens a motion. A photo
    whose walls fit two headings alike is then not stated to face one of them. Zeros
    without alternatives."""
    if not alternatives:
        return np.zeros(3)
    w = np.array([1.0] + [weight * min(max(float(r), 0.0), 1.0) for _, r in alternatives])
    d = np.array([a for a, _ in alternatives], float).reshape(-1, 3)
    return np.sqrt((w[1:] / w.sum()) @ d ** 2)
