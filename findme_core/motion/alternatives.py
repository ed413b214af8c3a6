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


#: rivals of an answer tested at most (``turns``): a room's other quarter turns and half turn
MAX_RIVALS = 3


def turns(cy, total, yaw: float, sep: float, k: int = MAX_RIVALS) -> list[int]:
    """Indices of up to ``k`` rivals (``rival``): the best-scoring candidate (yaw (C,)
    radians, score (C,)) more than ``sep`` radians from ``yaw``, then the best more than
    ``sep`` from it too, and so on: each of a symmetric room's other turns once."""
    cy, total = np.asarray(cy), np.asarray(total)
    out, left = [], np.ones(len(cy), bool)
    for _ in range(k):
        idx = np.flatnonzero(left)
        j = rival(cy[idx], total[idx], yaw, sep)
        if j is None:
            break
        out.append(int(idx[j]))
        left &= np.abs(wrap(cy - cy[out[-1]])) > sep
    return out


def more_agree(n_best: int, n_other: int) -> bool:
    """Whether more of the photos' matches agree with one motion than with another: the
    counts of agreeing matches differ by more than their standard error, sqrt(n_best +
    n_other) (chance agreements are counts: Poisson). Integers: the same on every machine."""
    return bool(n_best - n_other > np.sqrt(n_best + n_other))


def looks_more_alike(app_best: tuple, app_other: tuple) -> bool:
    """Whether the photos' appearance prefers one motion to another: (correlation, samples)
    of ``photometric.agreement`` each, the correlations differing by more than their
    standard error (1 / sqrt(samples) each). With nothing seen by either (0 samples) it
    cannot tell, and the layouts that scored the motions decide: True."""
    (cb, nb), (co, no) = app_best, app_other
    return not (nb > 0 and no > 0 and bool(cb - co <= np.sqrt(1.0 / nb + 1.0 / no)))


def same(y1: float, t1, y2: float, t2) -> bool:
    """Whether two motions (yaw radians, (x, z) metres) are one: yaws within 3 deg and
    positions within 0.1 m plus 10 % of the first's baseline."""
    dt = np.hypot(t1[0] - t2[0], t1[1] - t2[1])
    return bool(abs(np.angle(np.exp(1j * (y1 - y2)))) < np.radians(3.0)
                and dt < 0.1 + 0.1 * np.hypot(*t1[:2]))


def distinct(motions, whys) -> tuple[list[int], int]:
    """The distinct motions of refined candidates, best first, and the best one the evidence
    determines.

    Args:
        motions: ``PlanarMotion`` (n,), best first.
        whys: (n,) why the evidence does not determine each (an exception), None when it
            does.
    Returns:
        (indices of the distinct motions (``same``: the first of each, unless a later one
        the evidence determines is the same motion as an undetermined one, which it then
        replaces: two refinements of one motion from different starts, one of which weighed
        too few lifted points; dev pair zpl_r06_p11_p12_t1, its scale at +-13 m), the
        position among them of the first determined one).
    Raises:
        The first motion's ``why`` when none is determined.
    """
    out: list[int] = []
    for i, m in enumerate(motions):
        twin = next((j for j, o in enumerate(out) if same(m.yaw, (m.x, m.z), motions[o].yaw,
                                                           (motions[o].x, motions[o].z))), None)
        if twin is None:
            out.append(i)
        elif whys[i] is None and whys[out[twin]] is not None:
            out[twin] = i
    k = next((j for j, i in enumerate(out) if whys[i] is None), None)
    if k is None:
        raise whys[out[0]]
    return out, k


def on_the_way(yaw: float, x: float, z: float, yaws, xs, zs) -> np.ndarray:
    """(n,) whether each of n motions (yaws radians, B at (xs, zs) metres) has the turn and
    the direction of travel of the motion (yaw, x, z), both within 3 deg: the same way at
    another distance (or the same motion)."""
    tol = np.radians(3.0)
    turn = wrap(np.arctan2(np.asarray(xs, float), np.asarray(zs, float)) - np.arctan2(x, z))
    return (np.abs(wrap(np.asarray(yaws, float) - yaw)) < tol) & (np.abs(turn) < tol)


def along(best: PlanarMotion, others, cy, ct, evidence, ratio: float, k: int) -> list:
    """Up to k candidates, none the same as ``best`` or ``others`` (its alternatives so far),
    at ``best``'s yaw and baseline direction (``on_the_way``) but at another distance,
    among the candidates (yaw (C,) radians, t (C, 3) metres): [(index, share)] of the
    distinct ones whose evidence for their distance is at least ``ratio`` of ``best``'s
    (share: theirs over ``best``'s), the most first.

    The metric scale of a motion rests on depths lifted from one photo (floor points, wall
    points, the walls themselves), and a wrong boundary (a counter's front taken for the wall,
    a shadow for the floor line) puts them at another depth: the matches, which fix the
    direction, cannot tell the two distances apart. ``evidence(yaw (n,), t (n, 3))`` -> (n,)
    is the part of the score that sees the distance (``Fit.scale_score``: the lifted points'
    transfer, the layouts, the baseline prior), not the epipolar residuals, which every
    distance along one direction shares. The candidates are kept as scored (``as_scored``),
    not refined: the refinement slides them back to ``best``.
    """
    near = np.flatnonzero(on_the_way(best.yaw, best.x, best.z, cy, ct[:, 0], ct[:, 2]))
    ref = float(evidence(np.array([best.yaw]), np.array([[best.x, best.dy, best.z]]))[0])
    if len(near) == 0 or not ref > 0.0:   # nothing tells any distance from another
        return []
    ev = np.asarray(evidence(np.asarray(cy)[near], ct[near]), float)
    out: list[tuple[int, float]] = []
    seen = [(m.yaw, (m.x, m.z)) for m in (best, *others)]
    for j in ties.order(ev):
        i, e = int(near[j]), float(ev[j])
        if len(out) == k or e < ratio * ref:
            break
        yaw, t = float(cy[i]), ct[i, [0, 2]]
        if any(same(yaw, t, y, q) for y, q in seen):
            continue
        seen.append((yaw, t))
        out.append((i, e / ref))
    return out


def as_scored(best: PlanarMotion, yaw: float, t3, share: float, inliers, lifted_a, lifted_b,
              layout) -> PlanarMotion:
    """A candidate (yaw radians, t3 (3,) metres) kept as scored, not refined, as an
    alternative of ``best``: its own evidence (``inliers`` (M,) bool, of them those lifted in
    photo A and in B (M,) bool, the layouts' ``layout`` agreement), ``best``'s sigmas scaled
    by the distance ratio, and ``best``'s score times ``share`` (its evidence over
    ``best``'s, ``along``); its appearance not measured."""
    t3, n_scale = np.asarray(t3, float), int(np.sum(lifted_a) + np.sum(lifted_b))
    f = float(np.hypot(t3[0], t3[2])) / max(float(np.hypot(best.x, best.z)), 1e-9)
    return replace(best, x=float(t3[0]), dy=float(t3[1]), z=float(t3[2]), yaw=float(yaw),
                   sigma_x=best.sigma_x * f, sigma_z=best.sigma_z * f, inliers=inliers,
                   n_scale=n_scale, layout=layout, score=best.score * share, alternatives=(),
                   appearance=(float("nan"), 0))


def spread_over(m: PlanarMotion) -> PlanarMotion:
    """``m`` with its sigmas widened to cover its alternatives: the variance of the mixture of
    it and them, weighted by score (the 1-sigma of an answer the evidence cannot tell from
    another one includes the other one).

    The evidence that cannot tell the turn between the photos cannot tell the direction of
    travel either (``turned``): the translation is widened as well by the answer's own
    translation turned by +-s about photo A, s the alternatives' spread in yaw. Dev pairs
    (2026-12-01, the dataset's gravity): of the 12 ZInD answers stated with a yaw 1-sigma
    over 30 deg, 9 were over 1 m off, 3 of them beyond 3 sigma in x or z."""
    if not m.alternatives:
        return m
    cands = (m, *m.alternatives)
    w = np.array([max(c.score, 1e-9) for c in cands])
    w /= w.sum()
    dx = np.array([c.x - m.x for c in cands])
    dz = np.array([c.z - m.z for c in cands])
    dyaw = np.angle(np.exp(1j * np.array([c.yaw - m.yaw for c in cands])))
    vyaw = float(w @ dyaw ** 2)
    tx, tz = turned(m.x, m.z, float(np.sqrt(vyaw)))
    return replace(m, sigma_x=float(np.sqrt(m.sigma_x ** 2 + w @ dx ** 2 + tx ** 2)),
                   sigma_z=float(np.sqrt(m.sigma_z ** 2 + w @ dz ** 2 + tz ** 2)),
                   sigma_yaw=float(np.sqrt(m.sigma_yaw ** 2 + vyaw)))


def turned(x: float, z: float, s: float) -> tuple[float, float]:
    """(sx, sz) metres: the spread on each axis of photo B's position (x, z) metres in A's
    level frame turned by +s and -s radians about A (an equal mixture of the two; s beyond a
    quarter turn counts as a quarter turn). A position turned by s moves by
    (x (cos s - 1) - z sin s, x sin s + z (cos s - 1)): the mixture's variance per axis is
    the mean of the two moves' squares."""
    s = min(abs(s), np.pi / 2)
    c, n = 1.0 - np.cos(s), np.sin(s)
    return (float(np.sqrt((x * c) ** 2 + (z * n) ** 2)),
            float(np.sqrt((z * c) ** 2 + (x * n) ** 2)))
