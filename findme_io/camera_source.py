"""A photo's camera and gravity from what is known about it, in order of trust.

    lens:    given (intrinsics or a field of view)  >  EXIF focal length  >  the default
    gravity: given (sensors, flags, dataset)         >  the image's vanishing directions  >  level

Used alike by the command line, ``findme eval`` and the services (``convert.frame_camera``),
so a photo gets the same camera everywhere. Returns a ``findme_core`` Camera and its
``Provenance``.
"""

from __future__ import annotations

import math

import numpy as np

from dataclasses import replace

from findme_core.geometry.camera import DEFAULT_HFOV_DEG, Camera
from findme_core.single.gravity_fusion import with_sensor
from findme_core.single.hypotheses import HypothesisSet
from findme_core.single.methods import hypothesize
from findme_core.single.photo import hypothesize_estimated
from findme_core.geometry.provenance import INPUT_GRAVITY_SIGMA_DEG, Provenance, tilt_cov
from findme_core.single.vanishing import estimate_gravity, level_estimate

from .exif import ExifInfo, focal_px


def lens_camera(width: int, height: int, intrinsics=None, hfov_deg: float | None = None,
                exif: ExifInfo | None = None) -> tuple[Camera, str, tuple[str, ...]]:
    """(level Camera of the upright ``width`` x ``height`` image, camera source, notes).

    Args:
        intrinsics: (fx, fy, cx, cy) in pixels of this image, or None.
        hfov_deg: horizontal field of view, degrees, or None (used when no intrinsics).
        exif: the photo's EXIF facts (used when neither is given).
    Raises:
        CameraError: invalid intrinsics or field of view.
    """
    if intrinsics is not None:
        fx, fy, cx, cy = intrinsics[:4]
        return Camera(fx, fy, cx, cy, width, height), "input", ()
    if hfov_deg is not None:
        return Camera.from_hfov(hfov_deg, width, height), "input", ()
    notes: list[str] = list(exif.notes) if exif is not None else []
    if exif is not None:
        f, _, more = focal_px(exif, width, height)
        notes += more
        if f is not None:
            return (Camera(f[0], f[1], (width - 1) / 2.0, (height - 1) / 2.0, width, height),
                    "exif", tuple(notes))
    notes.append(f"no focal length in the photo: a {DEFAULT_HFOV_DEG:g} deg field of view "
                 "(a typical phone camera) assumed")
    return Camera.from_hfov(DEFAULT_HFOV_DEG, width, height), "default", tuple(notes)


def with_gravity(camera: Camera, image: np.ndarray | None, gravity=None,
                 gravity_sigma_rad: float | None = None, estimate: bool = True,
                 camera_source: str = "input", notes=()) -> tuple[Camera, Provenance]:
    """The camera with its gravity and the provenance of both: the given one combined with
    the image's vanishing directions near it (``gravity_fusion.with_sensor``: source
    "input+image", or "input" when the image cannot tell); the given one as it is when
    ``estimate`` is off, no image is given or its sigma is 0 (exact); without a given one,
    the image's estimate (when ``estimate`` and an image is given), else level.

    Args:
        camera: intrinsics (its own gravity is ignored).
        image: (H, W, 3) uint8 BGR of ``camera``'s size, or None.
        gravity: (3,) given gravity in camera coordinates, or None.
        gravity_sigma_rad: 1-sigma of a given gravity per axis (default
            ``INPUT_GRAVITY_SIGMA_DEG``; 0: exact).
    """
    if gravity is not None:
        s = math.radians(INPUT_GRAVITY_SIGMA_DEG) if gravity_sigma_rad is None else gravity_sigma_rad
        cov = tilt_cov(s)
        if not (estimate and image is not None) or s == 0.0:
            return camera.with_gravity(gravity), Provenance(camera_source, "input", cov,
                                                            tuple(notes))
        camera.with_gravity(gravity)          # a bad vector is named as the caller gave it
        est = with_sensor(image, camera, gravity, cov)
        extra = (est.reason,) if est.reason else ()
        return (camera.with_gravity(est.vector),
                Provenance(camera_source, est.source, est.cov, tuple(notes) + extra, est))
    if not (estimate and image is not None):
        est = level_estimate("no gravity given and the image was not used: level assumed")
        return (camera.with_gravity(est.vector),
                Provenance(camera_source, est.source, est.cov, tuple(notes) + (est.reason,)))
    est = estimate_gravity(image, camera)
    extra = (est.reason,) if est.reason else ()
    return (camera.with_gravity(est.vector),
            Provenance(camera_source, est.source, est.cov, tuple(notes) + extra, est))


def hypothesize_photo(image: np.ndarray, camera: Camera, prov: Provenance,
                      method: str = "findme", max_n: int = 10, clock=None,
                      camera_height: float | None = None
                      ) -> tuple[HypothesisSet, Camera, Provenance]:
    """The photo's hypotheses, and its camera and provenance after them.

    A photo whose gravity was estimated from its image (``with_gravity``: ``prov.estimate``)
    reuses that estimate's segments, and its gravity may be refined jointly with the best
    boundary (``photo.hypothesize_estimated``): the camera and provenance returned then
    carry the refined gravity and covariance. Otherwise ``methods.hypothesize`` with
    ``camera`` as it is.

    Args:
        image: (H, W, 3) uint8 BGR of ``camera``'s size.
        camera, prov: from ``with_gravity`` / ``photo_camera`` of this image.
        camera_height: metres above the floor when known (the walls behind kitchen
            counters, ``counters``); None when the scale is unknown.
    """
    est = prov.estimate
    if est is None:
        return (hypothesize(image, camera, method, max_n, clock=clock,
                            camera_height=camera_height), camera, prov)
    hs, new = hypothesize_estimated(image, camera, est, method, max_n, clock=clock,
                                    camera_height=camera_height)
    if new is est:
        return hs, camera, prov
    return hs, camera.with_gravity(new.vector), replace(prov, gravity_cov=new.cov, estimate=new)


def photo_camera(image: np.ndarray, exif: ExifInfo | None = None, intrinsics=None,
                 hfov_deg: float | None = None, gravity=None,
                 gravity_sigma_rad: float | None = None,
                 estimate: bool = True) -> tuple[Camera, Provenance]:
    """Camera and provenance of a decoded photo (``lens_camera`` then ``with_gravity``)."""
    H, W = image.shape[:2]
    cam, source, notes = lens_camera(W, H, intrinsics, hfov_deg, exif)
    return with_gravity(cam, image, gravity, gravity_sigma_rad, estimate, source, notes)


def camera_json(camera: Camera, prov: Provenance) -> dict:
    """The ``"camera"`` and ``"gravity"`` objects of the JSON answers (degrees at the edge)."""
    r = lambda x: round(float(x), 6)  # noqa: E731
    return {
        "camera": {"fx": r(camera.fx), "fy": r(camera.fy), "cx": r(camera.cx), "cy": r(camera.cy),
                   "hfov_deg": r(math.degrees(2 * math.atan(camera.width / (2 * camera.fx)))),
                   "source": prov.camera},
        "gravity": {"vector": [r(x) for x in camera.gravity], "source": prov.gravity,
                    "sigma_deg": r(math.degrees(prov.gravity_sigma)),
                    "pitch_deg": r(camera.pitch_deg), "roll_deg": r(camera.roll_deg)},
        "notes": list(prov.notes),
    }
