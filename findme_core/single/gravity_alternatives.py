"""Other vertical directions a photo's lines support nearly as well as the best one.

A Manhattan frame is fixed by its vertical and one horizontal vanishing direction. When one
family of parallel lines dominates a photo (floorboards, tiles, a striped rug, a wall of
shelves), every frame that makes that family horizontal explains most of the lines, and
frames tens of degrees apart score within a few percent of each other: the photo alone
cannot tell gravity, and a tight 1-sigma around the best of them would be a confident wrong
answer. This module names such frames (``distinct``) and widens the best estimate's tilt
covariance to cover them (``widen``: the covariance of the mixture of the best and its
alternatives about the best, weighted by score, as ``motion/alternatives.spread_over`` does
for motions).

Frames: gravity vectors are unit 3-vectors in camera coordinates (x right, y down, z
forward), pointing down; tilts are in radians along the best estimate's level z axis
(pitch) and x axis (roll), as ``vanishing.GravityEstimate.cov``. Pure numpy.
"""

from __future__ import annotations

import math

import numpy as np

from findme_core.geometry.manhattan import pitch_roll_deg


def down(g: np.ndarray) -> np.ndarray:
    """(3,) unit ``g`` pointing down (y > 0)."""
    g = np.asarray(g, float) / np.linalg.norm(g)
    return -g if g[1] < 0 else g


def angle_deg(a: np.ndarray, b: np.ndarray) -> float:
    """Angle between two gravity directions, degrees (sign-free: both point down)."""
    return math.degrees(math.acos(float(np.clip(abs(down(a) @ down(b)), -1.0, 1.0))))


def distinct(best: np.ndarray, best_score: float, others, ratio: float,
             distinct_deg: float) -> tuple[tuple[np.ndarray, float], ...]:
    """The frames that score at least ``ratio`` of the best and whose gravity lies more
    than ``distinct_deg`` from the best's and from each other's.

    Args:
        best: (3,) the best frame's gravity.
        best_score: its score (> 0).
        others: iterable of ((3,) gravity, score) of the other refined frames.
    Returns:
        ((gravity (3,), score / best_score), ...), the strongest first (ties by angle to
        the best, then by the vector: the same order on every machine).
    """
    if not best_score > 0:
        return ()
    cands = [(down(g), float(s) / best_score) for g, s in others
             if s is not None and np.isfinite(s) and s >= ratio * best_score]
    cands.sort(key=lambda c: (-round(c[1], 6), round(angle_deg(best, c[0]), 4),
                              tuple(np.round(c[0], 6))))
    out: list[tuple[np.ndarray, float]] = []
    for g, r in cands:
        if angle_deg(best, g) > distinct_deg and all(angle_deg(g, q) > distinct_deg
                                                    for q, _ in out):
            out.append((g, r))
    return tuple(out)


def tilt_offset(g: np.ndarray, other: np.ndarray) -> np.ndarray:
    """(2,) radians: ``other``'s pitch and roll minus ``g``'s (roll wrapped to +-pi)."""
    p0, r0 = pitch_roll_deg(down(g))
    p1, r1 = pitch_roll_deg(down(other))
    dr = (r1 - r0 + 180.0) % 360.0 - 180.0
    return np.radians([p1 - p0, dr])


def widen(g: np.ndarray, cov: np.ndarray, alternatives, weight: float = 1.0) -> np.ndarray:
    """(2, 2) tilt covariance of the mixture of the estimate (``g``, ``cov``; weight 1)
    and its ``alternatives`` ((gravity, score ratio), ...; weight = ``weight`` x ratio: how
    often an alternative this strong is the right frame, fitted on data), about ``g``:
    cov + sum_k w_k d_k d_k^T with w normalised over all and d_k the alternative's tilt
    offset. Unchanged without alternatives."""
    cov = np.asarray(cov, float)
    if not alternatives:
        return cov
    w = np.array([1.0] + [weight * max(r, 0.0) for _, r in alternatives])
    w = w / w.sum()
    out = cov.copy()
    for wk, (a, _) in zip(w[1:], alternatives):
        d = tilt_offset(g, a)
        out = out + wk * np.outer(d, d)
    return out


def describe(g: np.ndarray, alternatives) -> str:
    """One sentence naming the strongest alternative: the reason a photo's gravity is
    uncertain."""
    a, r = alternatives[0]
    p, roll = pitch_roll_deg(down(a))
    more = f" (and {len(alternatives) - 1} more)" if len(alternatives) > 1 else ""
    return (f"gravity is ambiguous in this photo: another vertical direction "
            f"{angle_deg(g, a):.0f} deg away (pitch {p:.0f}, roll {roll:.0f} deg) explains "
            f"its lines {100 * r:.0f} % as well{more}; its 1-sigma covers both (give the "
            "phone's gravity to decide)")
