"""One entry point for every hypothesis method, at a working resolution.

Parameters of the methods are in pixels tuned for ~640 px images; a 12 MP phone photo is
processed at ``work_size`` on its long side and the polylines are mapped back to the
photo's pixels (pixel-centre convention: u_full = (u_work + 0.5) / s - 0.5).
"""

from __future__ import annotations

from dataclasses import replace

import cv2
import numpy as np

from . import hypotheses, paper
from .camera import Camera
from .errors import InputError

METHODS = ("findme", "paper")
WORK_SIZE = 640


def hypothesize(image: np.ndarray, camera: Camera, method: str = "findme", max_n: int = 10,
                work_size: int = WORK_SIZE, clock=None) -> hypotheses.HypothesisSet:
    """Ranked hypotheses of one photo by ``method`` ("findme" or "paper").

    Args:
        image: (H, W, 3) uint8 BGR, the size of ``camera``.
        max_n: at most this many hypotheses (>= 1).
    """
    if method not in METHODS:
        raise InputError(f"unknown method {method!r}; choose one of {', '.join(METHODS)}")
    if max_n < 1:
        raise InputError(f"--max must be at least 1, got {max_n}")
    H, W = image.shape[:2]
    s = min(1.0, work_size / max(H, W))
    if s < 0.95:
        small = cv2.resize(image, (round(W * s), round(H * s)), interpolation=cv2.INTER_AREA)
        cam = camera.scaled(s)
        cam = Camera(cam.fx, cam.fy, cam.cx, cam.cy, small.shape[1], small.shape[0], cam.gravity)
    else:
        s, small, cam = 1.0, image, camera
    gen = hypotheses.generate if method == "findme" else paper.generate
    hs = gen(small, cam, max_n, clock=clock)
    if s == 1.0:
        return hs
    hyps = []
    for h in hs.hypotheses:
        poly = (h.polyline + 0.5) / s - 0.5
        poly[0, 0], poly[-1, 0] = 0.0, W - 1.0
        hyps.append(replace(h, polyline=poly))
    return replace(hs, width=W, height=H, hypotheses=hyps)
