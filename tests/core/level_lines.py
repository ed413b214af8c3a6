"""Straight lines of exact scenes built in a photo's level frame (x right, y down, z
forward; the floor at y = camera height), projected with the camera: the test suite's
kitchen counters (``test_counters``) and furniture tops (``test_tops``)."""

from __future__ import annotations

import numpy as np

from findme_core.geometry.camera import Camera
from findme_core.geometry.manhattan import gravity_of


def camera(pitch: float = 25.0, roll: float = 0.0) -> Camera:
    """A 640 x 480 phone camera (70 deg across) pitched and rolled (degrees)."""
    return Camera.from_hfov(70.0, 640, 480, gravity=gravity_of(pitch, roll))


def seg(cam: Camera, a, b) -> np.ndarray:
    """(4,) the image segment [u1, v1, u2, v2] of the level-frame 3D segment a-b."""
    uv, front = cam.project_level(np.array([a, b], float))
    assert front.all()
    return np.concatenate([uv[0], uv[1]])


def hline(cam: Camera, h_cam: float, z: float, height: float, xs) -> np.ndarray:
    """(4,) the image of a level 3D line along x (from xs[0] to xs[1]) at depth z,
    ``height`` above the floor of a camera ``h_cam`` above it."""
    y = h_cam - height
    return seg(cam, (xs[0], y, z), (xs[1], y, z))
