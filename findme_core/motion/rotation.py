"""The rotation between the CAMERA frames of two photos taken turning at one spot, from
their feature matches alone: no gravity, no layout. It carries one photo's gravity to the
other (gravity is one direction in the world: g_A = M g_B), which is how photos without
phone sensors agree on which way is down (``pair_gravity``, ``plan.shared_gravity``).

A pure rotation: b_A = M b_B for every match's unit camera bearings; two bearings fix M
(Kabsch), seeded 2-match consensus. Photos from two places show parallax, and few matches
agree on one rotation: then there is none. (The essential matrix's rotation would serve
them in principle; on the dev split's real rooms it was off by 3.9 deg median, 22 deg at
the 97th percentile, far beyond its own covariance: walls, floors and cabinets are planes,
where the essential matrix degenerates. So it is not used.)

Frames: camera coordinates (x right, y down, z forward); M (3, 3) maps B's camera
coordinates to A's. Units: pixels for the matches and thresholds. Pure numpy.
"""

from __future__ import annotations

import numpy as np

from findme_core.geometry.camera import Camera
from findme_core.motion.features import Matches


def camera_bearings(camera: Camera, pixels) -> np.ndarray:
    """(N, 3) unit rays of pixels (N, 2) in the camera frame (K^-1 [u, v, 1])."""
    px = np.asarray(pixels, float).reshape(-1, 2)
    r = np.column_stack([(px[:, 0] - camera.cx) / camera.fx, (px[:, 1] - camera.cy) / camera.fy,
                         np.ones(len(px))])
    return r / np.linalg.norm(r, axis=1, keepdims=True)


def kabsch(a, b) -> np.ndarray:
    """(3, 3) the rotation M minimising sum |a_i - M b_i|^2 (a, b: (N, 3) unit vectors)."""
    U, _, Vt = np.linalg.svd(a.T @ b)
    d = np.sign(np.linalg.det(U @ Vt))
    return U @ np.diag([1.0, 1.0, d]) @ Vt


def kabsch_batch(a, b) -> np.ndarray:
    """(S, 3, 3) ``kabsch`` of S sets of pairs at once (a, b: (S, K, 3) unit vectors)."""
    U, _, Vt = np.linalg.svd(a.transpose(0, 2, 1) @ b)
    d = np.sign(np.linalg.det(U @ Vt))
    D = np.tile(np.eye(3), (len(d), 1, 1))
    D[:, 2, 2] = d
    return U @ D @ Vt


def accepts(k: int, n: int, min_inliers: int, min_fraction: float) -> bool:
    """Whether k agreeing matches of n make a model."""
    return k >= min_inliers and k >= min_fraction * n


def pure_rotation(matches: Matches, cam_a: Camera, cam_b: Camera, residual_px: float,
                  min_inliers: int, min_fraction: float, iterations: int = 200,
                  seed: int = 0) -> tuple[np.ndarray, int] | None:
    """(M, inliers) of the pure rotation most matches agree on, or None when fewer than
    ``min_inliers`` (or ``min_fraction`` of them) do.

    Seeded 2-match samples (two bearings fix a rotation), each fitted by Kabsch; the one
    with the most matches within ``residual_px`` (at A's focal length) wins (ties: the
    first), then it is refitted on its inliers twice.
    """
    n = len(matches.ua)
    if n < max(min_inliers, 2):
        return None
    ba, bb = camera_bearings(cam_a, matches.ua), camera_bearings(cam_b, matches.ub)
    thr = residual_px / cam_a.fx
    rng = np.random.default_rng(seed)
    ij = np.array([rng.choice(n, 2, replace=False) for _ in range(iterations)])
    # every sample at once: one direction fixes no rotation (skipped), the others by Kabsch
    ok = np.linalg.norm(np.cross(ba[ij[:, 0]], ba[ij[:, 1]]), axis=1) >= 1e-3
    if not ok.any():
        return None
    Ms = kabsch_batch(ba[ij[ok]], bb[ij[ok]])
    counts = (np.linalg.norm(ba[None] - bb[None] @ Ms.transpose(0, 2, 1), axis=2)
              < thr).sum(axis=1)
    best, best_k = Ms[int(np.argmax(counts))], int(counts.max())   # ties: the first sample
    if not accepts(best_k, n, min_inliers, min_fraction):
        return None
    for _ in range(2):
        inl = np.linalg.norm(ba - bb @ best.T, axis=1) < thr
        if inl.sum() < 3:
            return None
        best = kabsch(ba[inl], bb[inl])
    k = int((np.linalg.norm(ba - bb @ best.T, axis=1) < thr).sum())
    return (best, k) if accepts(k, n, min_inliers, min_fraction) else None
