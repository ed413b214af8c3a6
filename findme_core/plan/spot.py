"""Photos taken turning at one spot: the yaw between two of them from their feature matches,
whether they share a position at all, and a session's spots found so (``auto_spots``).

A user maps a room by standing at a few spots and turning round at each. Two photos of one
spot differ by a pure rotation about gravity, so with gravity known (each photo's level
frame) a matched point's level bearing b_A (unit, level frame of A) is the bearing b_B of B
turned by the yaw alone: b_A = R_y(yaw) b_B, R_y = [[c, 0, s], [0, 1, 0], [-s, 0, c]]
(DESIGN.md: level_A <- level_B, yaw > 0 when B is turned right of A). Hence azimuths
(atan2(x, z)) add, az_A = az_B + yaw, and elevations agree. One match gives a yaw
(1-point consensus); photos from two different spots show parallax, and few matches agree
on one yaw, so the consensus also tells the spots apart.

Gravity is never exact (a phone's sensor, each photo's own estimate): tilts a degree apart
move the bearings by ~8 px, beyond the yaw's residual. When the yaw alone leaves too few
matches, the rotation is fitted whole: b_A = M b_B with M any rotation (Kabsch, on the
matches a 1-point yaw gathers within ``tilt_tol_deg``, then re-selected at
``residual_px``); still a pure rotation, so parallax still tells two spots apart, and the
turn is accepted when M tilts the vertical by at most ``tilt_tol_deg``. Its yaw is M's
about the vertical: atan2(M[0, 2], M[2, 2]).

Units: radians inside; pixels for the matches. Pure numpy; no I/O.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from findme_core.geometry.camera import Camera
from findme_core.motion import rotation
from findme_core.motion.features import Matches
from findme_core.plan.fuse import Link


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
        tilt_tol_deg: the photos' gravities may disagree by this much (the whole rotation
            is then fitted, see the module doc).
    """

    residual_px: float = 2.0
    min_inliers: int = 10
    min_fraction: float = 0.05
    sigma_floor_deg: float = 0.1
    tilt_tol_deg: float = 3.0


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
    found = _yaw_only(ba, bb, yaws, thr, params)
    return found if found is not None else _whole_rotation(ba, bb, yaws, thr, params,
                                                           cam_a.fx)


def _consensus(ba, bb, yaws, thr):
    """The 1-point yaw with the most matches within ``thr`` (every match's yaw a hypothesis,
    exhaustive: n is a few hundred), and those matches."""
    n = len(ba)
    best, best_in = 0.0, np.zeros(n, bool)
    for y in yaws[:: max(1, n // 400)]:
        inl = np.linalg.norm(ba - _turn(y, bb), axis=1) < thr
        if inl.sum() > best_in.sum():
            best, best_in = y, inl
    return best, best_in


def _accepts(k: int, n: int, params: SpotParams) -> bool:
    return rotation.accepts(k, n, params.min_inliers, params.min_fraction)


def _whole_rotation(ba, bb, yaws, thr, params: SpotParams, fx: float) -> SpotYaw | None:
    """The turn as a whole rotation M (b_A = M b_B, level frames) when the gravities
    disagree (module doc), or None."""
    tol = np.radians(params.tilt_tol_deg)
    _, inl = _consensus(ba, bb, yaws, thr + 2 * np.sin(tol / 2))
    for _ in range(3):
        if not _accepts(int(inl.sum()), len(ba), params):
            return None
        M = rotation.kabsch(ba[inl], bb[inl])
        res = np.linalg.norm(ba - bb @ M.T, axis=1)
        inl = res < thr
    k = int(inl.sum())
    tilt = np.arccos(np.clip(M[1, 1], -1.0, 1.0))     # how far M moves the vertical
    if not _accepts(k, len(ba), params) or tilt > tol:
        return None
    yaw = float(np.arctan2(M[0, 2], M[2, 2]))
    rms = float(np.sqrt(np.mean(res[inl] ** 2)))
    return SpotYaw(yaw, max(rms / np.sqrt(k), np.radians(params.sigma_floor_deg)), k, len(ba),
                   rms * fx)


def camera_rotation(matches: Matches, cam_a: Camera, cam_b: Camera,
                    params: SpotParams = SpotParams(), iterations: int = 200,
                    seed: int = 0) -> tuple[np.ndarray, int] | None:
    """The rotation M with b_A = M b_B between the CAMERA frames of two photos taken at one
    spot (no gravity needed: ``shared_gravity`` uses it to carry one photo's gravity to
    the other), or None when fewer than ``min_inliers`` matches (or ``min_fraction`` of
    them) agree on one pure rotation (``rotation.pure_rotation``). Returns (M (3, 3),
    inliers).
    """
    return rotation.pure_rotation(matches, cam_a, cam_b, params.residual_px,
                                  params.min_inliers, params.min_fraction, iterations, seed)


def _yaw_only(ba, bb, yaws, thr, params: SpotParams) -> SpotYaw | None:
    """The turn as a yaw about the photos' common gravity (module doc), or None."""
    n = len(ba)
    best, best_in = _consensus(ba, bb, yaws, thr)
    if not best_in.any():
        return None
    for _ in range(3):   # refine: circular mean of the inliers' yaws, then re-select
        best = float(np.angle(np.mean(np.exp(1j * yaws[best_in]))))
        res = np.linalg.norm(ba - _turn(best, bb), axis=1)
        best_in = res < thr
        if not best_in.any():
            return None
    k = int(best_in.sum())
    if not _accepts(k, n, params):
        return None
    spread = np.angle(np.exp(1j * (yaws[best_in] - best)))
    sigma = max(float(np.std(spread)) / np.sqrt(k), np.radians(params.sigma_floor_deg))
    return SpotYaw(float(np.angle(np.exp(1j * best))), sigma, k, n,
                   float(np.sqrt(np.mean(res[best_in] ** 2))) * params.residual_px / thr)


def auto_spots(photos, match, turn=None) -> tuple[list[int], list]:
    """(spot label per photo (N,), the rotation ``fuse.Link`` s that joined them), capture
    order. Photo j joins the current spot when it
    shares a rotation-only yaw (``rotation_yaw``) with one of the spot's photos (the
    latest first); else, when it shares one with a photo of the spot before, the current
    spot was part of that one's turn (a gap of left-out views: no overlap across it) and
    both are one spot again; else it starts a new spot. ``match(i, j)`` gives the
    matches of photos i < j; ``turn(i, j)``, if given, their ``rotation_yaw`` (a cached
    one), else it is computed from the matches.

    Every photo of the spot counts, not only the one before: a turn that skips views (too
    little floor, a blurred photo) or comes round to its first photo still overlaps some
    photo of it; rotation-only consensus refuses photos taken at another spot (parallax).
    """
    if turn is None:
        def turn(i, j):
            return rotation_yaw(match(i, j), photos[i].camera, photos[j].camera)

    def turned(members, j):   # the link to the latest photo of ``members`` j turned from
        for i in reversed(members):
            r = turn(i, j)
            if r is not None:
                return Link(i, j, r.yaw, r.sigma)
        return None

    lab, links, cur, prev = [], [], [], []
    for j in range(len(photos)):
        k = turned(cur, j) if cur else None
        if k is None and prev:
            k = turned(prev, j)
            if k is not None:
                for i in cur:
                    lab[i] = lab[prev[0]]
                cur, prev = prev + cur, []
        if k is None:
            prev, cur = cur, []
        else:
            links.append(k)
        cur.append(j)
        lab.append(lab[cur[0]] if len(cur) > 1 else (max(lab) + 1 if lab else 0))
    return lab, links
