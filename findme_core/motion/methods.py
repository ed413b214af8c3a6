"""Planar camera motion between two photos (paper step 5): the default estimator, which
registers the two photos' room layouts together with their feature matches, and dispatch.

Frames and units (DESIGN.md): each photo has a level frame (y down along gravity, z the
optical axis projected on the horizontal plane, x right). The motion of a pair (A, B) is
the pose of camera B in A's level frame: X_A = R_y(yaw) X_B + t for level-frame points,
t = (x, dy, z) metres, yaw radians (> 0: B turned right of A); dy is expected near
h_A - h_B. Per match i: unit level bearings a_i (A), b_i (B) and, where a photo's chosen
hypothesis gives one, its lifted 3D point (paper eqs. 2-4). Per photo: the layouts of its
candidate hypotheses (``layout.Layout``, the chosen one first) and the room's orientation
from its lines (``orientation.Orientation``).

Estimators (``METHODS``):

* ``findme`` (default): (1) yaws: the two photos' room orientations (their difference
  modulo 90 deg: four candidates in a box room), the feature matches' free gravity-aware
  epipolar RANSAC, and walls of B turned onto walls of A. (2) Per yaw, the baseline
  directions the matches agree on (one match fixes the direction of a known-yaw motion:
  t . (R_y b x a) = 0), each scaled by the lifted points' consensus, by a wall of B put on
  a wall of A, and by a 1-D search of the layouts' agreement; and the translations two
  non-parallel walls or a corner fix on their own (textureless walls: no match at all).
  Matches lifted in one photo only give candidates too: placed in the other photo by
  their height (the level frames share the vertical), each is a 3D-3D correspondence that
  fixes t at a known yaw (``motion_lifted``: a photo that sees no floor, placed by the other
  photo's walls). (3) Every candidate is scored by the matches (MSAC of epipolar and
  lifted transfer residuals, pixels), the layouts (``register``: boundary samples of each
  photo on the other's walls, minus samples on floor the other photo sees) and the orientations; the
  best distinct ones are refined by robust Levenberg-Marquardt of (yaw, x, dy, z) on all
  three, and ranked. Motions the evidence allows nearly as well (a symmetric room) are the
  answer's ``alternatives``. Near-duplicate matches (one corner at several ORB pyramid
  levels, ``features.distinct``) count once.
* ``features`` (``motion_features``): the matches alone (the default before layouts).
* ``lifted``, ``paper`` (``motion_baselines``): 2-point Kabsch on lifted matches; the
  paper's eqs. 5-8 on the ``features`` RANSAC's verified matches.

Every estimate carries its inliers and 1-sigma uncertainties (covariance of the fit, inflated
by the robust chi^2 per degree of freedom, plus model errors). Degenerate input raises
``MotionError`` naming the cause. Pure: numpy in, numbers out; seeded randomness.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from findme_core.geometry.camera import Camera
from findme_core.errors import InputError
from findme_core.motion.features import Lifted, Matches, distinct
from findme_core.motion.feature_motion import Lifter, features_estimate
from findme_core.motion.model import MotionInputs, MotionParams, PlanarMotion, motion_result  # noqa: F401
from findme_core.motion.estimator import Registration

METHODS = ("findme", "features", "lifted", "paper")


def estimate(matches: Matches, cam_a: Camera, cam_b: Camera, h_a: float, h_b: float,
             lift_a: Lifter | None, lift_b: Lifter | None, method: str = "findme",
             params: MotionParams = MotionParams(), *, layouts=((), ()),
             orientations=(None, None), surfaces=(None, None)) -> PlanarMotion:
    """Planar motion of B in A's level frame.

    Args:
        matches: putative matches (pixels of A and B); may be empty for ``findme``.
        cam_a, cam_b: intrinsics and gravity of each photo.
        h_a, h_b: camera heights above the floor, metres.
        lift_a, lift_b: match indices -> ``Lifted`` of all matches (3D where computed), e.g.
            ``lambda i: features.lift(scene_a, matches.ua, i)``; None for a photo without
            a usable hypothesis. At most ``params.max_lift`` matches are asked for.
        method: one of ``METHODS``.
        layouts: (A's, B's) sequences of ``layout.Layout`` of candidate hypotheses, the
            chosen one first (``findme`` only).
        orientations: (A's, B's) ``orientation.Orientation`` or None (``findme`` only).
        surfaces: (A's, B's) ``motion_photometric.Surface`` (the photo's samples placed by
            its chosen layout) or None (``findme`` only).

    Raises:
        MotionError: too few matches and no common wall, identical photos, no common view,
            only parallel walls in common and no match, no 3D for scale.
    """
    if method not in METHODS:
        raise InputError(f"unknown motion method {method!r}; choose one of {', '.join(METHODS)}")
    if method != "findme":
        return features_estimate(matches, cam_a, cam_b, h_a, h_b, lift_a, lift_b, method, params)
    keep, rep = distinct(matches, params.duplicate_px)   # copies of one corner count once
    m = Registration(matches.subset(keep), cam_a, cam_b, h_a, h_b, _subset(lift_a, keep),
                     _subset(lift_b, keep), layouts, orientations, params,
                     len(matches) - len(keep), surfaces).run()
    return _expanded(m, rep)


def _subset(lift: Lifter | None, keep) -> Lifter | None:
    """The lifter of the kept matches (indices into ``keep``)."""
    if lift is None:
        return None

    def sub(idx):
        L = lift(keep[np.asarray(idx, int)])
        return Lifted(L.points[keep], L.sigma[keep], L.floor[keep])
    return sub


def _expanded(m: PlanarMotion, rep) -> PlanarMotion:
    """``m`` (and its alternatives) with inliers over all matches: a copy is an inlier when
    the match it copies is."""
    return replace(m, inliers=m.inliers[rep],
                   alternatives=tuple(_expanded(a, rep) for a in m.alternatives))
