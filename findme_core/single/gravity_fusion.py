"""A sensor's gravity refined by the photo's own vanishing directions.

A phone's accelerometer gives gravity to ~0.5 deg held still and to 1-3 deg while the hand
moves; the photo's vertical and horizontal lines give it too (``vanishing``), with their own
covariance. Both measure one direction, so they are combined as two Gaussian measurements of
its tilt (information-weighted mean, the product of the two Gaussians): the result is better
known than either, and a photo the lines cannot tell keeps the sensor's gravity.

1. The vanishing directions are searched only within ``window_sigmas`` of the sensor's tilt
   (at least ``min_window_deg``): the sensor is the prior, and a Manhattan frame 40 deg away
   (a rug's stripes) cannot be taken.
2. The image's estimate and the sensor's are combined (``combine``).
3. Once the photo has a boundary, ``floor_gravity.with_floor`` may re-estimate gravity without the
   floor lines' pull; ``photo.hypothesize_estimated`` combines that with the sensor again
   (``GravityEstimate.prior``).

A sensor covariance of 0 means the given gravity is exact: it is returned as it is.

Frames: camera coordinates (x right, y down, z forward). A tilt is the displacement of the
unit gravity along its level frame's z axis (forward: pitch) and x axis (right: roll), in
radians; covariances (2, 2) rad^2 in those axes, as ``vanishing.GravityEstimate.cov``.
Pure numpy; no I/O.
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np

from findme_core.errors import CameraError
from findme_core.geometry.camera import Camera
from findme_core.geometry.manhattan import pitch_roll_deg
from findme_core.single.segments import Segments
from findme_core.single.vanishing import GravityEstimate, GravityParams, estimate_gravity

#: the sources of a combined estimate and of a sensor's gravity the image could not refine
FUSED, SENSOR = "input+image", "input"


def level_axes(g: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(z, x) unit axes of the level frame of the unit gravity g (3,): forward (the optical
    axis projected) and right, the directions of a pitch and a roll tilt."""
    x = np.cross(g, [0.0, 0.0, 1.0])
    n = np.linalg.norm(x)
    if n < 1e-9:
        raise CameraError(f"gravity {np.round(g, 6).tolist()} is along the optical axis: "
                          "the photo looks straight up or down, its tilt has no level frame")
    x /= n
    return np.cross(x, g), x


def combine(g_a, cov_a, g_b, cov_b) -> tuple[np.ndarray, np.ndarray]:
    """The information-weighted mean of two measurements of one gravity.

    Args:
        g_a, g_b: (3,) unit gravities, a few degrees apart at most.
        cov_a, cov_b: (2, 2) tilt covariances, rad^2, positive definite.
    Returns:
        (unit gravity (3,), its (2, 2) covariance (cov_a^-1 + cov_b^-1)^-1).
    """
    g_a = np.asarray(g_a, float) / np.linalg.norm(g_a)
    g_b = np.asarray(g_b, float) / np.linalg.norm(g_b)
    zl, xl = level_axes(g_a)
    d = g_b - g_a
    delta = np.array([d @ zl, d @ xl])            # b's tilt from a, in a's level axes
    info_a, info_b = np.linalg.inv(cov_a), np.linalg.inv(cov_b)
    cov = np.linalg.inv(info_a + info_b)
    t = cov @ (info_b @ delta)                    # a's own tilt from a is 0
    g = g_a + t[0] * zl + t[1] * xl
    return g / np.linalg.norm(g), cov


def with_sensor(image: np.ndarray, camera: Camera, sensor, sensor_cov,
                params: GravityParams = GravityParams(), segments: Segments | None = None,
                window_sigmas: float = 4.0, min_window_deg: float = 6.0) -> GravityEstimate:
    """The sensor's gravity combined with the photo's vanishing directions near it.

    Args:
        image: (H, W, 3) uint8 BGR (or (H, W) grey), the size of ``camera``.
        camera: intrinsics of the photo (its gravity is ignored).
        sensor: (3,) the sensor's gravity in camera coordinates (any length > 0).
        sensor_cov: (2, 2) its tilt covariance, rad^2 (0: exact, returned as it is).
        segments: the photo's ``segments.photo_segments`` when already detected.
    Returns:
        GravityEstimate with source ``FUSED`` and ``prior`` = (sensor, sensor_cov); or the
        sensor's gravity with source ``SENSOR`` and the reason when the image cannot tell (or
        when the sensor is exact), carrying the segments for the hypotheses either way.
    """
    g = np.asarray(sensor, float).reshape(3)
    if not np.all(np.isfinite(g)) or np.linalg.norm(g) < 1e-9:
        raise CameraError(f"gravity must be a finite non-zero 3-vector, got {g.tolist()}")
    g = g / np.linalg.norm(g)
    C = np.asarray(sensor_cov, float)
    if C.shape != (2, 2) or not np.all(np.isfinite(C)):
        raise CameraError(f"a sensor's tilt covariance must be a finite 2x2 matrix, got {C!r}")
    sigma_deg = math.degrees(math.sqrt(max(np.trace(C), 0.0) / 2.0))
    if sigma_deg > 0.0 and np.linalg.eigvalsh(0.5 * (C + C.T)).min() <= 0.0:
        raise CameraError(f"a sensor's tilt covariance must be positive definite (or 0: "
                          f"exact), got {C.tolist()}")
    if sigma_deg == 0.0:
        return GravityEstimate(g, C, SENSOR, reason="the given gravity is exact (sigma 0)",
                               segments=segments)
    if math.hypot(g[0], g[1]) < 1e-6:
        return GravityEstimate(g, C, SENSOR, reason="the photo looks straight up or down: "
                               "the sensor's gravity kept", segments=segments)
    pitch, roll = pitch_roll_deg(g)
    w = max(window_sigmas * sigma_deg, min_window_deg)
    near = replace(params, pitch_range=(pitch - w, pitch + w), roll_range=(roll - w, roll + w),
                   peaks=2, candidates=1,     # the window holds one frame: refine its best
                   ambiguity_candidates=0)    # (the sensor decides between frames in it)
    est = estimate_gravity(image, camera, near, segments)
    if est.source != "image":       # the estimator's reason, said of the window it searched
        why = (est.reason or "").removesuffix(": level assumed").replace(
            "outside the tilt of a hand-held photo", f"more than {w:.0f} deg from the sensor's")
        return GravityEstimate(g, C, SENSOR, reason=f"the sensor's gravity kept: {why}",
                               segments=est.segments)
    return fused(est, (g, C))


def fused(est: GravityEstimate, prior: tuple) -> GravityEstimate:
    """An image estimate ``est`` combined with the sensor's ``prior`` = (gravity (3,), tilt
    covariance (2, 2)); the prior is kept on it for a later re-estimate."""
    g, C = combine(prior[0], prior[1], est.vector, est.cov)
    return replace(est, vector=g, cov=C, source=FUSED, prior=prior)
