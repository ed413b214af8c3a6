"""One-sided lifting: motion candidates from matches lifted to 3D in ONE photo only (the
other photo sees no floor: a blank wall, cabinets seen close), for the ``findme`` estimator
(``estimator``).

Frames and units (DESIGN.md, ``methods``): X_A = R_y(yaw) X_B + t, t = (x, dy, z) metres, yaw
radians; level frames share the vertical (y down). A match lifted in A to P_A (its floor or
wall point, ``features.lift``) lies at height y_B = P_A,y - dy in B's level frame, and B's
unit bearing b of it reaches that height at depth lambda = y_B / b_y, so X_B = lambda b: the
match is a 3D-3D correspondence (P_A, X_B) although B has no 3D of its own (symmetrically
X_A = (P_B,y + dy) / a_y a for a match lifted in B). On the floor plane (x, z), at a known yaw (the room orientations', the free epipolar RANSAC's, the walls'), ONE
correspondence gives t = P_A - R(yaw) X_B (``at_yaw``: every lifted match votes, the modes
are the candidates). (Pairs of correspondences give yaw and t too, by 2-D Kabsch; on the dev
pairs they found no motion the known yaws missed, so they are not drawn.)

The depth along b is lambda = y_B / b_y, so a height error dy_err moves X_B by dy_err / tan(e)
horizontally (e: b's elevation); points within ``min_elev_deg`` of the horizon say nothing.
Pure numpy.
"""

from __future__ import annotations

import numpy as np

from findme_core.geometry.planar import _rot2
from findme_core.motion.model import MotionInputs


def correspondences(P: MotionInputs, min_elev_deg: float = 3.0, height_sigma: float = 0.03):
    """Floor-plane correspondences of the matches lifted in one photo and placed in the other
    by their height.

    Args:
        P: bearings and lifted points of the matches (``MotionInputs``; P.dy = h_A - h_B).
        min_elev_deg: bearings closer to the horizon than this are left out.
        height_sigma: 1-sigma of the point's height in the other photo beyond the lifted
            point's own (camera heights, a floor that is not flat), metres.

    Returns:
        (pa (K, 2), pb (K, 2), sigma (K,), match (K,)): A's and B's (x, z) of each
        correspondence in its own level frame, metres; 1-sigma of the horizontal
        disagreement, metres; the match index.
    """
    out = []
    sin_min = np.sin(np.radians(min_elev_deg))
    for L, rays, sign in ((P.la, P.b, -1.0), (P.lb, P.a, 1.0)):
        i = np.flatnonzero(L.valid)
        if len(i) == 0:
            continue
        pts, r, s0 = L.points[i], rays[i], L.sigma[i]
        y = pts[:, 1] + sign * P.dy            # the point's height in the other photo
        ok = np.abs(r[:, 1]) > sin_min
        with np.errstate(divide="ignore", invalid="ignore"):
            lam = np.where(ok, y / r[:, 1], -1.0)
        ok &= lam > 0
        other = lam[:, None] * r
        own_dir = pts / np.maximum(np.linalg.norm(pts, axis=1, keepdims=True), 1e-12)
        sig_y = np.hypot(height_sigma, s0 * np.abs(own_dir[:, 1]))
        tan_e = np.abs(r[:, 1]) / np.maximum(np.hypot(r[:, 0], r[:, 2]), 1e-12)
        sig = np.hypot(s0, sig_y / np.maximum(tan_e, 1e-12))
        k = np.flatnonzero(ok & np.isfinite(sig))
        own, oth = pts[k][:, [0, 2]], other[k][:, [0, 2]]
        pa, pb = (own, oth) if sign < 0 else (oth, own)
        out.append((pa, pb, sig[k], i[k]))
    if not out:
        return np.zeros((0, 2)), np.zeros((0, 2)), np.zeros(0), np.zeros(0, int)
    return tuple(np.concatenate(c) for c in zip(*out))


def _modes(t, sig, gate: float, k: int, min_support: float, sep_m: float):
    """The k best-supported distinct translations among the votes t (N, 2) (support: MSAC
    of the other votes' distances over their sigma); (K, 2), support (K,)."""
    dx, dz = t[:, None, 0] - t[None, :, 0], t[:, None, 1] - t[None, :, 1]
    dist = np.sqrt(dx * dx + dz * dz)   # (N, N) metres (the norm over the pair axis)
    support = np.maximum(0.0, 1.0 - (dist / (gate * sig[None])) ** 2).sum(1)
    keep, far = [], np.ones(len(t), bool)   # far: farther than sep_m from every kept mode
    for i in np.argsort(-support, kind="stable"):
        if support[i] < min_support or len(keep) == k:
            break
        if far[i]:
            keep.append(i)
            far &= dist[i] > sep_m
    keep = np.array(keep, int)
    return t[keep], support[keep]


def at_yaw(corr, yaw: float, gate: float = 3.0, k: int = 3, min_support: float = 2.0,
           sep_m: float = 0.15) -> np.ndarray:
    """Translations (x, z) the one-sided correspondences agree on at one known yaw.

    Args:
        corr: ``correspondences`` (pa, pb, sigma, match).
        yaw: radians.
        gate: votes within ``gate`` sigmas support each other.
        k: at most this many modes; min_support: a mode needs this much support (MSAC:
            about 2 agreeing votes, its own included); sep_m: modes closer than this are one.

    Returns:
        (C, 2) candidate translations, metres, best supported first.
    """
    pa, pb, sig, _ = corr
    if len(pa) < 2:
        return np.zeros((0, 2))
    return _modes(pa - _rot2(yaw, pb), sig, gate, k, min_support, sep_m)[0]
