"""Photos taken turning at one spot: the yaw between two of them from their feature matches,
and whether they share a position at all.

A user maps a room by standing at a few spots and turning round at each. Two photos of one
spot differ by a pure rotation about gravity, so with gravity known (each photo's level
frame) a matched point's level bearing b_A (unit, level frame of A) is the bearing b_B of B
turned by the yaw alone: b_A = R_y(yaw) b_B, R_y = [[c, 0, s], [0, 1, 0], [-s, 0, c]]
(DESIGN.md: level_A <- level_B, yaw > 0 when B is turned right of A). Hence azimuths
(atan2(x, z)) add, az_A = az_B + yaw, and elevations agree. One match gives a yaw
(1-point consensus); photos from two different spots show parallax, and few matches agree
on one yaw, so the consensus also tells the spots apart.

Units: radians inside; pixels for the matches. Pure numpy; no I/O.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .camera import Camera
from .features import Matches


@dataclass(frozen=True)
class SpotParams:
    """Thresholds of the rotation-only consensus.

    Attributes:
        residual_px: a match agrees with a yaw when its bearings differ by less than this
            many pixels (at the focal length of A) after the turn.
        min_inliers: fewer agreeing matches do not make a rotation.
        min_fraction: nor do fewer than this fraction of the matches (parallax between
            two spots leaves most matches off any single yaw).
        sigma_floor_deg: the yaw's 1-sigma is never below this (gravity and pixel model
            errors that averaging does not remove).
    """

    residual_px: float = 2.0
    min_inliers: int = 10
    min_fraction: float = 0.05
    sigma_floor_deg: float = 0.1


@dataclass(frozen=True)
class SpotYaw:
    """Rotation-only yaw between two photos of one spot.

    Attributes:
        yaw: heading of B relative to A, radians in (-pi, pi], > 0 when B is turned right.
        sigma: its 1-sigma, radians.
        inliers: matches that agree with it.
        matches: matches there were.
        rms_px: rms residual of the inliers, pixels.
    """

    yaw: float
    sigma: float
    inliers: int
    matches: int
    rms_px: float


def _bearings(camera: Camera, pixels) -> np.ndarray:
    r = camera.rays_level(np.asarray(pixels, float).reshape(-1, 2))
    return r / np.linalg.norm(r, axis=1, keepdims=True)


def _turn(yaw, b):
    """R_y(yaw) b for bearings (N, 3)."""
    c, s = np.cos(yaw), np.sin(yaw)
    return np.column_stack([c * b[:, 0] + s * b[:, 2], b[:, 1], -s * b[:, 0] + c * b[:, 2]])


def rotation_yaw(matches: Matches, cam_a: Camera, cam_b: Camera,
                 params: SpotParams = SpotParams()) -> SpotYaw | None:
    """The yaw of B relative to A if the photos were taken at one spot, else None.

    Args:
        matches: putative matches, pixels ``ua`` in A and ``ub`` in B.
        cam_a, cam_b: intrinsics and gravity of A and B.

    Returns:
        The consensus yaw, or None when fewer than ``min_inliers`` matches (or fewer than
        ``min_fraction`` of them) agree on one turn: the photos do not overlap, or were
        taken at different spots.
    """
    n = len(matches.ua)
    if n < params.min_inliers:
        return None
    ba, bb = _bearings(cam_a, matches.ua), _bearings(cam_b, matches.ub)
    yaws = np.arctan2(ba[:, 0], ba[:, 2]) - np.arctan2(bb[:, 0], bb[:, 2])
    thr = params.residual_px / cam_a.fx
    # every match's yaw as a hypothesis (1-point consensus, exhaustive: n is a few hundred)
    best, best_in = 0.0, np.zeros(n, bool)
    for y in yaws[:: max(1, n // 400)]:
        inl = np.linalg.norm(ba - _turn(y, bb), axis=1) < thr
        if inl.sum() > best_in.sum():
            best, best_in = y, inl
    if not best_in.any():
        return None
    for _ in range(3):   # refine: circular mean of the inliers' yaws, then re-select
        best = float(np.angle(np.mean(np.exp(1j * yaws[best_in]))))
        res = np.linalg.norm(ba - _turn(best, bb), axis=1)
        best_in = res < thr
        if not best_in.any():
            return None
    k = int(best_in.sum())
    if k < params.min_inliers or k < params.min_fraction * n:
        return None
    spread = np.angle(np.exp(1j * (yaws[best_in] - best)))
    sigma = max(float(np.std(spread)) / np.sqrt(k), np.radians(params.sigma_floor_deg))
    return SpotYaw(float(np.angle(np.exp(1j * best))), sigma, k, n,
                   float(np.sqrt(np.mean(res[best_in] ** 2))) * cam_a.fx)
