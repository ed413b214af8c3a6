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
