"""The best distinct candidates of a motion estimate and the spread of its alternatives:
motions the evidence cannot tell apart (a symmetric room) widen the answer's 1-sigma.

Candidates are yaw (C,) radians, t (C, 3) metres in photo A's level frame (x right, y down,
z forward), score (C,); ``PlanarMotion`` as ``model``. Pure numpy.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from findme_core.geometry import ties
from findme_core.geometry.planar import wrap
from findme_core.motion.model import PlanarMotion


def distinct_top(cy, ct, total, k: int) -> np.ndarray:
    """Indices of the k best-scoring candidates (yaw (C,), t (C, 3), score (C,)) that are
    not copies of a better one (the same yaw and t: a scale found twice)."""
    order = ties.order(total)
    _, first = np.unique(np.column_stack([cy, ct])[order], axis=0, return_index=True)
    return order[np.sort(first)[:k]]


def rival(cy, total, yaw: float, sep: float) -> int | None:
    """Index of the best-scoring candidate (yaw (C,) radians, score (C,)) whose yaw is more
    than ``sep`` radians from ``yaw`` (a clearly different motion: another wall taken for
    this one in a symmetric room), None when there is none; ties broken as ``ties.order``."""
    far = np.flatnonzero(np.abs(wrap(np.asarray(cy) - yaw)) > sep)
    if len(far) == 0:
        return None
    return int(far[ties.order(np.asarray(total)[far])[0]])


def along(best: PlanarMotion, others, cy, ct, evidence, ratio: float, k: int, same) -> tuple:
    """Up to k motions, none the same as ``best`` or ``others`` (its alternatives so far), at
    ``best``'s yaw and baseline direction (both within 3 deg) but at another distance, among
    the candidates (yaw (C,) radians, t (C, 3) metres): the distinct ones whose evidence for
    their distance is at least ``ratio`` of ``best``'s, the most first.

    The metric scale of a motion rests on depths lifted from one photo (floor points, wall
    points, the walls themselves), and a wrong boundary (a counter's front taken for the wall,
    a shadow for the floor line) puts them at another depth: the matches, which fix the
    direction, cannot tell the two distances apart. ``evidence(yaw (n,), t (n, 3))`` -> (n,)
    is the part of the score that sees the distance (``Fit.scale_score``: the lifted points'
    transfer, the layouts, the baseline prior), not the epipolar residuals, which every
    distance along one direction shares. The candidates are kept as scored, not refined (the
    refinement slides them back to ``best``). Each gets ``best``'s sigmas scaled by its
    distance ratio and ``best``'s score times its evidence's share of ``best``'s;
    ``same(yaw1, (x1, z1), yaw2, (x2, z2))`` says whether two motions are one.
    """
    tol, base = np.radians(3.0), max(float(np.hypot(best.x, best.z)), 1e-9)
    turn = wrap(np.arctan2(ct[:, 0], ct[:, 2]) - np.arctan2(best.x, best.z))
    near = np.flatnonzero((np.abs(wrap(np.asarray(cy) - best.yaw)) < tol) & (np.abs(turn) < tol))
    ref = float(evidence(np.array([best.yaw]), np.array([[best.x, best.dy, best.z]]))[0])
    if len(near) == 0 or not ref > 0.0:   # nothing tells any distance from another
        return ()
    ev = np.asarray(evidence(np.asarray(cy)[near], ct[near]), float)
    out: list[PlanarMotion] = []
    for j in ties.order(ev):
        i, e = near[j], float(ev[j])
        if len(out) == k or e < ratio * ref:
            break
        yaw, t = float(cy[i]), ct[i, [0, 2]]
        if any(same(yaw, t, m.yaw, (m.x, m.z)) for m in (best, *others, *out)):
            continue
        f = float(np.hypot(*t)) / base
        out.append(replace(best, x=float(t[0]), z=float(t[1]), yaw=yaw, sigma_x=best.sigma_x * f,
                           sigma_z=best.sigma_z * f, score=best.score * e / ref,
                           alternatives=()))
    return tuple(out)


def spread_over(m: PlanarMotion) -> PlanarMotion:
    """``m`` with its sigmas widened to cover its alternatives: the variance of the mixture of
    it and them, weighted by score (the 1-sigma of an answer the evidence cannot tell from
    another one includes the other one)."""
    if not m.alternatives:
        return m
    cands = (m, *m.alternatives)
    w = np.array([max(c.score, 1e-9) for c in cands])
    w /= w.sum()
    dx = np.array([c.x - m.x for c in cands])
    dz = np.array([c.z - m.z for c in cands])
    dyaw = np.angle(np.exp(1j * np.array([c.yaw - m.yaw for c in cands])))
    return replace(m, sigma_x=float(np.sqrt(m.sigma_x ** 2 + w @ dx ** 2)),
                   sigma_z=float(np.sqrt(m.sigma_z ** 2 + w @ dz ** 2)),
                   sigma_yaw=float(np.sqrt(m.sigma_yaw ** 2 + w @ dyaw ** 2)))
