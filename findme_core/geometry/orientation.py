"""The room's orientation in one photo: the dominant horizontal direction of its straight
lines modulo 90 degrees (walls, ceiling edges, window and cabinet edges of a Manhattan room),
in the photo's level frame (x right, z forward, y down; azimuth atan2(x, z), radians). It
needs no floor in view; two photos' orientations give their relative yaw modulo 90 degrees.

Pure numpy; no I/O.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from findme_core.geometry.camera import Camera


@dataclass(frozen=True)
class Orientation:
    """The room's dominant horizontal direction in a photo's level frame, modulo 90 deg.

    Attributes:
        angle: azimuth of the direction, radians in [0, pi / 2) (atan2(x, z) of a wall's
            direction, modulo a quarter turn).
        support: length-weighted fraction of the photo's horizontal line evidence within
            2 degrees of it (0..1).
        n_lines: lines that took part.
    """

    angle: float
    support: float
    n_lines: int


def orientation(segments, camera: Camera, min_vertical_deg: float = 10.0,
                resolution_deg: float = 0.25, spread_deg: float = 1.5) -> Orientation | None:
    """Dominant horizontal direction (mod 90 deg) of the 3D lines seen as ``segments``.

    Each image segment with its camera centre spans a plane (normal n, level frame); a
    horizontal 3D line in it has direction n x g = (-n_z, 0, n_x). Segments whose plane is
    within ``min_vertical_deg`` of vertical are left out (the images of vertical lines, and
    horizontal lines seen end-on, which look alike); the others vote with weight length x
    (1 - n_y^2) (the direction is ill-defined near the horizon) on a circular histogram of
    4 x angle, smoothed by ``spread_deg``.

    Args:
        segments: (N, 4) image segments [u1, v1, u2, v2], pixels.

    Returns:
        The orientation, or None without a usable line.
    """
    seg = np.asarray(segments, float).reshape(-1, 4)
    if len(seg) == 0:
        return None
    n = np.cross(camera.rays_level(seg[:, :2]), camera.rays_level(seg[:, 2:]))
    n /= np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-12)
    horiz = np.hypot(n[:, 0], n[:, 2])                 # sin of the plane's tilt from level
    ok = np.abs(n[:, 1]) > np.sin(np.radians(min_vertical_deg))
    if not ok.any():
        return None
    ang = np.arctan2(-n[ok, 2], n[ok, 0])
    w = np.hypot(*(seg[ok, 2:] - seg[ok, :2]).T) * horiz[ok] ** 2
    grid = np.radians(np.arange(0.0, 90.0, resolution_deg))
    k = 1.0 / (4.0 * np.radians(spread_deg)) ** 2
    score = np.exp((np.cos(4.0 * (grid[:, None] - ang[None])) - 1.0) * k) @ w
    best = grid[int(np.argmax(score))]
    near = np.abs(np.angle(np.exp(4j * (ang - best)))) < 4 * np.radians(2.0)
    # sub-bin angle: circular mean of the nearby votes
    best = float(np.angle(np.sum(w[near] * np.exp(4j * ang[near]))) / 4.0) % (np.pi / 2)
    return Orientation(best, float(w[near].sum() / max(w.sum(), 1e-12)), int(ok.sum()))
