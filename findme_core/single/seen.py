"""Which walls of a boundary the photo shows.

A hypothesis's polyline may run outside the image: the boundary continued below (or above)
the photo's edge, where nobody saw the base of the wall. Such a wall's distance is an
inference from the hypothesis's shape, not a measurement, and ``scene.Scene.locate`` gives
its points no answer.

Frames and units: image pixels (u right, v down); a wall's floor line (unit normal n, offset)
in the camera's level frame, metres, as ``scene.Scene`` builds it. Pure numpy; no I/O.
"""

from __future__ import annotations

import numpy as np

#: a WALL segment of the boundary with less of its length inside the image than this (pixels)
#: was not seen: the hypothesis continued it below (or above) the photo's edge, so the
#: distance of the wall on it is an inference (``scene.Scene.locate`` refuses its points;
#: measured 2026-11-30 on the dev split with a phone's gravity: 235 of the 6541 ZInD wall
#: points said to be on a wall, 13 % of them beyond 3 sigma against 6.6 % of all). One pixel:
#: any part seen counts; not fitted.
MIN_SEEN_PX = 1.0


def seen_px(poly: np.ndarray, height: int) -> np.ndarray:
    """(M - 1,) length in pixels of each segment of the (M, 2) polyline inside the image's
    rows, -0.5 <= v <= height - 0.5 (pixel centres at integers; the polyline's u lies within
    the image by construction)."""
    a, b = poly[:-1], poly[1:]
    dv = b[:, 1] - a[:, 1]
    top, bottom = -0.5, height - 0.5
    with np.errstate(divide="ignore", invalid="ignore"):
        t_lo = np.where(dv != 0, (top - a[:, 1]) / dv, np.where(a[:, 1] >= top, -np.inf, np.inf))
        t_hi = np.where(dv != 0, (bottom - a[:, 1]) / dv,
                        np.where(a[:, 1] <= bottom, np.inf, -np.inf))
    t0 = np.clip(np.maximum(np.minimum(t_lo, t_hi), 0.0), 0.0, 1.0)
    t1 = np.clip(np.minimum(np.maximum(t_lo, t_hi), 1.0), 0.0, 1.0)
    return np.maximum(t1 - t0, 0.0) * np.hypot(b[:, 0] - a[:, 0], dv)


def walls_seen(poly, height: int, wall, normal, offset) -> np.ndarray:
    """(M - 1,) whether each segment of the (M, 2) polyline ``poly`` (pixels of an image
    ``height`` rows high) has its wall seen; ``wall`` (M - 1,) bool: the segment is a wall,
    ``normal`` (M - 1, 2) and ``offset`` (M - 1,): its floor line n . (x, z) = offset in the
    level frame (metres). A wall is seen when some segment of its run of
    consecutive WALL segments on one floor line (normals within 1 deg, offsets within 2 %)
    has at least ``MIN_SEEN_PX`` inside the image (a dense polyline splits one wall into
    many short segments, some of them below the image)."""
    same = (wall[:-1] & wall[1:] & ((normal[:-1] * normal[1:]).sum(1) > np.cos(np.radians(1.0)))
            & (np.abs(offset[:-1] - offset[1:])
               <= 0.02 * np.maximum(np.abs(offset[:-1]), np.abs(offset[1:]))))
    run = np.concatenate([[0], np.cumsum(~same)])
    seen = np.zeros(run[-1] + 1, bool)
    np.logical_or.at(seen, run, seen_px(poly, height) >= MIN_SEEN_PX)
    return seen[run]
