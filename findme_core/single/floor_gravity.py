"""Gravity again once a photo's ground-wall boundary is known (``with_floor``): the lines
below it lie on the floor, horizontal in any direction, so they may only count as vertical;
the frame is searched again near the first estimate without their pull, and the first
estimate's alternatives (``vanishing`` step 5) are scored again without it.

Frames and units as ``vanishing``: pixels with the pixel-centre origin, directions in the
camera frame (x right, y down, z forward), angles in radians. Pure numpy.
"""

from __future__ import annotations

import math

import numpy as np

from findme_core.geometry.manhattan import LineSet, pitch_roll_deg, residuals, score_frames
from findme_core.single import gravity_alternatives as alt
from findme_core.single.vanishing import (GravityEstimate, GravityParams, _estimate, _frame,
                                          with_alternatives)


def with_floor(est: GravityEstimate, polyline: np.ndarray,
               params: GravityParams = GravityParams()) -> GravityEstimate:
    """Gravity again, knowing the photo's ground-wall boundary.

    The lines lying more than ``floor_margin_px`` below ``polyline`` are on the floor:
    horizontal in unknown directions, so they may only count as vertical lines. Without
    them the frame is searched within ``floor_window_deg`` of ``est`` and refined; the new
    estimate is taken when it explains the remaining lines better by ``min_gain``.
    Nothing changes when ``est`` is not from the image (alone or combined with a sensor's:
    the new estimate is then the image's alone), when the floor region holds more
    than ``max_floor_vertical_px`` of vertical lines (objects stand there: it is not the
    floor's edge) or less than ``min_floor_px`` of other lines (nothing pulls).

    Args:
        est: an estimate of ``estimate_gravity`` (source "image", with its evidence).
        polyline: (M, 2) boundary vertices in pixels of the photo (u non-decreasing).
    The alternatives of ``est`` (step 5) are scored again without the floor lines' pull:
    those that no longer score ``ambiguity_ratio`` of the estimate are dropped (the
    floorboards that made them were on the floor).

    Returns:
        ``est`` itself, or the joint estimate.
    """
    p = params
    if est.source not in ("image", "input+image") or est.evidence is None:
        return est
    L, K, s = est.evidence
    poly = (np.asarray(polyline, float).reshape(-1, 2) + 0.5) * s - 0.5   # to working pixels
    on_floor = L.mid[:, 1] > np.interp(L.mid[:, 0], poly[:, 0], poly[:, 1]) + p.floor_margin_px
    vertical = residuals(L, (K @ est.vector)[None])[:, 0] < 2 * math.sin(math.radians(p.inlier_deg))
    if (L.w[on_floor & vertical].sum() > p.max_floor_vertical_px
            or L.w[on_floor & ~vertical].sum() < p.min_floor_px):
        return est
    L2 = L.only_vertical(on_floor)
    pitch, roll = pitch_roll_deg(est.vector)
    w = p.floor_window_deg
    found = _frame(L2, K, p, (pitch - w, pitch + w), (roll - w, roll + w))
    if found is None:
        return _rescored(est, est, L2, K, p)
    new = _estimate(*found[:3], p, est.segments, est.evidence)
    if new.source != "image":
        return _rescored(est, est, L2, K, p)
    before, after = score_frames(L2, K, np.array([est.vector, new.vector]), p.inlier_deg)[0]
    return _rescored(new if after > (1.0 + p.min_gain) * before else est, est, L2, K, p)


def _rescored(chosen: GravityEstimate, est: GravityEstimate, L2: LineSet, K: np.ndarray,
              p: GravityParams) -> GravityEstimate:
    """``chosen`` with those of ``est``'s alternatives that the lines ``L2`` still support
    (``chosen`` itself when ``est`` had none)."""
    if not est.alternatives:
        return chosen
    others = [g for g, _ in est.alternatives]
    s, _ = score_frames(L2, K, np.array([chosen.vector, *others]), p.inlier_deg)
    kept = alt.distinct(chosen.vector, float(s[0]), zip(others, s[1:]), p.ambiguity_ratio,
                        p.distinct_deg)
    return with_alternatives(chosen, kept, p.alternative_weight)
