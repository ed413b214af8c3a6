"""One entry point for every hypothesis method, at a working resolution.

Parameters of the methods are in pixels tuned for ~640 px images; a 12 MP phone photo is
processed at ``work_size`` on its long side and the polylines are mapped back to the
photo's pixels (pixel-centre convention: u_full = (u_work + 0.5) / s - 0.5).
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from findme_core.single import counters, hypotheses, paper
from findme_core.geometry.camera import Camera
from findme_core.errors import InputError
from findme_core.single.segments import WORK_SIZE, Segments, photo_segments, work_image  # noqa: F401

METHODS = ("findme", "paper")


def hypothesize(image: np.ndarray, camera: Camera, method: str = "findme", max_n: int = 10,
                work_size: int = WORK_SIZE, clock=None,
                segments: Segments | None = None,
                camera_height: float | None = None) -> hypotheses.HypothesisSet:
    """Ranked hypotheses of one photo by ``method`` ("findme" or "paper").

    Args:
        image: (H, W, 3) uint8 BGR, the size of ``camera``.
        max_n: at most this many hypotheses (>= 1).
        segments: the photo's ``segments.photo_segments`` when already detected (its
            gravity came from them): then not detected again. Ignored by the paper's method.
        camera_height: metres above the floor, when known: the best hypothesis is then
            seen behind the kitchen counters it stands on (``counters.apply``; findme only).
    """
    if method not in METHODS:
        raise InputError(f"unknown method {method!r}; choose one of {', '.join(METHODS)}")
    if max_n < 1:
        raise InputError(f"--max must be at least 1, got {max_n}")
    H, W = image.shape[:2]
    small, cam, s = work_image(image, camera, work_size)
    if method == "findme":
        hs = hypotheses.generate(small, cam, max_n, clock=clock, segments=segments)
        hs = counters.apply(hs, cam, camera_height, max_n)   # at the working size
    else:
        hs = paper.generate(small, cam, max_n, clock=clock)
    if s == 1.0:
        return hs
    hyps = []
    for h in hs.hypotheses:
        poly = (h.polyline + 0.5) / s - 0.5
        poly[0, 0], poly[-1, 0] = 0.0, W - 1.0
        hyps.append(replace(h, polyline=poly))
    return replace(hs, width=W, height=H, hypotheses=hyps)
