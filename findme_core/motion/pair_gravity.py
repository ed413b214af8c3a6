"""Two photos of one spot agree on which way is down: an unsure gravity from one photo's
lines is completed by the other photo's, through their feature matches.

A photo without phone sensors finds gravity in its own lines (``single/vanishing``), and
some photos cannot tell: one dominant family of parallel lines fits frames tens of degrees
apart, and the estimate says so with a wide 1-sigma. A motion lifted on such a gravity is
wrong by as much (two photos turning 45 deg at one spot: 58 deg and 0.9 camera heights of
translation instead of 45 deg and none). Gravity is one direction in the world, and the
rotation M between two photos taken turning at one spot follows from their matches alone
(``rotation.pure_rotation``): A's gravity seen from B is M^T g_A. So B's gravity is carried
into A's frame and the two are combined by their information (the inverse-variance
weighted mean direction; a photo's alternatives take part as a spot's photos vote with
them, ``agree``):

    g = normalise(g_A / s_A^2 + M g_B / s_B'^2),  s_B'^2 = s_B^2 + s_link^2,
    1-sigma s = (1 / s_A^2 + 1 / s_B'^2)^-1/2),

and each UNSURE photo (1-sigma over ``unsure_deg``) takes the combined direction in its own
frame; a sure photo keeps its own (a link is less certain than a good photo's lines). When
the two disagree beyond ``conflict`` times their combined sigma, one of them is confidently
wrong: a gravity from the phone's sensors wins over one from lines; between two from lines
the pair cannot tell which, both keep their own and ``status`` says "disagree" (a motion
then refuses, ``pair.agreed_gravity``);
when the matches fix no rotation (photos from two places, or too few matches),
"unlinked".

Frames: gravity vectors are unit 3-vectors in each photo's camera coordinates (x right, y
down, z forward), pointing down; M maps B's camera coordinates to A's. Sigmas: one 1-sigma
angle per photo (``Provenance.unsensed_sigma``), radians inside, degrees in parameters;
infinite for a photo assumed level (no evidence: it takes the other's). Pure numpy.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from findme_core.geometry.camera import Camera
from findme_core.motion.features import Matches
from findme_core.motion.rotation import pure_rotation
from findme_core.single.gravity_alternatives import down

#: a gravity from the photo's lines less sure than this (1-sigma, degrees) is unsure: it is
#: completed by the other photo's, and said with the results that rest on it. A phone's
#: sensors are within 0.5-1.5 deg, and the models' errors were fitted on gravities that good.
UNSURE_GRAVITY_DEG = 5.0


@dataclass(frozen=True)
class PairGravityParams:
    """Attributes:
        residual_px, min_inliers, min_fraction: the pure rotation's consensus
            (``rotation.pure_rotation``), as ``plan.shared_gravity``'s.
        link_sigma_deg: 1-sigma of the gravity carried by M. Measured: A's true gravity
            carried to B against B's true one, over the 9 dev pairs whose matches agree on a
            pure rotation (6 TUM, 3 KITTI): median 0.9, 68th percentile 1.5, max 3.2 deg;
            fitted on all groups but one (KITTI, blocks of 10 TUM frames) the 68th
            percentile ranges 0.9-2.4 deg. Too few links to decide, so widened: 2.0 deg
            holds 6 of the 9 within 1 sigma and all within 3.
        alternative_sigma_deg: 1-sigma given to an alternative (it has no fit of its own), as
            ``plan.shared_gravity``'s.
        conflict: two gravities further apart than this many combined sigmas disagree.
        unsure_deg: photos whose own 1-sigma is above this take the combined gravity.
    """

    residual_px: float = 3.0
    min_inliers: int = 15
    min_fraction: float = 0.3
    link_sigma_deg: float = 2.0
    alternative_sigma_deg: float = 2.0
    conflict: float = 3.0
    unsure_deg: float = UNSURE_GRAVITY_DEG


@dataclass(frozen=True)
class PairGravity:
    """The gravities a pair's motion uses.

    Attributes:
        gravity_a, gravity_b: (3,) unit, each in its photo's camera frame.
        sigma_a, sigma_b: their 1-sigma, radians.
        status: "agreed" (each unsure photo took the combined gravity), "disagree" or
            "unlinked" (each kept its own: ``reason``).
        angle: the photos' own gravities apart, once carried into one frame, radians
            (nan when unlinked).
        inliers: matches that agree on the rotation (0 when unlinked).
        reason: one sentence for "disagree" and "unlinked", else None.
    """

    gravity_a: np.ndarray
    gravity_b: np.ndarray
    sigma_a: float
    sigma_b: float
    status: str
    angle: float
    inliers: int
    reason: str | None = None


def combine(g_a, sigma_a: float, g_b_in_a, sigma_b: float) -> tuple[np.ndarray, float]:
    """(unit direction, 1-sigma) of two estimates of one gravity in one frame (the module
    doc's equation); sigmas in radians, > 0, at most one infinite (no evidence)."""
    wa, wb = 1.0 / sigma_a ** 2, 1.0 / sigma_b ** 2
    g = wa * down(g_a) + wb * down(g_b_in_a)
    return g / np.linalg.norm(g), 1.0 / math.sqrt(wa + wb)


def unsure(sigma: float, params: PairGravityParams = PairGravityParams()) -> bool:
    """Whether a gravity of 1-sigma ``sigma`` (radians) is unsure."""
    return math.degrees(sigma) > params.unsure_deg


def agree(matches: Matches, cam_a: Camera, cam_b: Camera, sigma_a: float, sigma_b: float,
          params: PairGravityParams = PairGravityParams(),
          alternatives: tuple = ((), ()), given: tuple = (False, False)) -> PairGravity:
    """The gravities of photos A and B (their cameras' gravities, 1-sigma ``sigma_a`` /
    ``sigma_b`` radians, > 0; infinite: assumed level) completed through their matches
    (module doc). ``alternatives``: each photo's other vertical directions its lines support
    nearly as well ((3,) vectors, ``vanishing.GravityEstimate.alternatives``): the two photos
    agree on the pair of candidates (own or alternative) nearest in units of their combined
    sigma (own-own first on a tie), as a spot's photos vote (``plan.shared_gravity``).
    ``given``: whether each photo's gravity came from the phone's sensors; when a given
    gravity and one from the lines disagree, the lines are wrong: that photo takes the given
    one, carried ("agreed"). Two photos both assumed level have nothing to combine:
    "unlinked"."""
    own_a, own_b = down(cam_a.gravity), down(cam_b.gravity)
    if math.isinf(sigma_a) and math.isinf(sigma_b):
        return PairGravity(own_a, own_b, sigma_a, sigma_b, "unlinked", math.nan, 0,
                           "neither photo's lines show which way is down")
    rot = pure_rotation(matches, cam_a, cam_b, params.residual_px, params.min_inliers,
                        params.min_fraction)
    if rot is None:
        return PairGravity(own_a, own_b, sigma_a, sigma_b, "unlinked", math.nan, 0,
                           "their matches agree on no rotation about one spot")
    M, k = rot
    link = math.radians(params.link_sigma_deg)
    s_alt = math.radians(params.alternative_sigma_deg)
    cands_a = [(own_a, sigma_a)] + [(down(g), s_alt) for g in alternatives[0]]
    cands_b = [(down(M @ own_b), sigma_b)] + [(down(M @ down(g)), s_alt)
                                               for g in alternatives[1]]
    pairs = []
    for i, (ga, sa) in enumerate(cands_a):
        for j, (gb, sb) in enumerate(cands_b):
            spread = math.sqrt(sa ** 2 + sb ** 2 + link ** 2)
            ang = math.acos(float(np.clip(ga @ gb, -1.0, 1.0)))
            pairs.append((ang / spread, i + j, i, j, ang, spread))
    z, _, i, j, _, _ = min(pairs)          # ties: the photos' own estimates first
    angle, spread = pairs[0][4], pairs[0][5]
    if z > params.conflict and given[0] != given[1]:
        if given[0]:
            return PairGravity(own_a, down(M.T @ own_a), sigma_a, math.hypot(sigma_a, link),
                               "agreed", angle, k)
        return PairGravity(down(M @ own_b), own_b, math.hypot(sigma_b, link), sigma_b,
                           "agreed", angle, k)
    if z > params.conflict:
        return PairGravity(own_a, own_b, sigma_a, sigma_b, "disagree", angle, k,
                           f"their gravities are {math.degrees(angle):.0f} deg apart where "
                           f"their sigmas allow {math.degrees(spread):.1f} deg (1-sigma): "
                           "one of them is wrong")
    (ga, sa), (gb, sb) = cands_a[i], cands_b[j]
    g, s = combine(ga, sa, gb, math.hypot(sb, link))
    ga, sa = (g, s) if unsure(sigma_a, params) else (own_a, sigma_a)
    gb, sb = ((down(M.T @ g), math.hypot(s, link)) if unsure(sigma_b, params)
              else (own_b, sigma_b))
    return PairGravity(ga, gb, sa, sb, "agreed", angle, k)
