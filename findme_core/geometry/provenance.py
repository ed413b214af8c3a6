"""Where a photo's camera and gravity came from, and how well gravity is known.

* camera source: "input" (given: flags, the frame's lens, a dataset's intrinsics), "exif"
  (the photo's EXIF focal length), "default" (``camera.DEFAULT_HFOV_DEG``);
* gravity source: "input" (given: the phone's sensors, flags, a dataset; exact, or the
  image could not refine it), "input+image" (a given gravity combined with the image's
  vanishing directions near it, ``gravity_fusion``), "image" (vanishing directions alone,
  ``vanishing.estimate_gravity``), "level" (assumed: the image could not tell).

``gravity_cov`` is the (2, 2) covariance (rad^2) of gravity's tilt about the level frame's
x axis (pitch) and z axis (roll); ``scene.Scene`` propagates it into every 3D sigma.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from findme_core.errors import CameraError

CAMERA_SOURCES = ("input", "exif", "default")
GRAVITY_SOURCES = ("input", "input+image", "image", "level")
#: what a gravity's error is like (``Provenance.gravity_kind``), best first
GRAVITY_KINDS = ("exact", "sensor", "image")
#: 1-sigma of a given gravity (a phone held still: its accelerometer's tilt error), degrees.
INPUT_GRAVITY_SIGMA_DEG = 0.5


def tilt_cov(sigma_rad: float) -> np.ndarray:
    """(2, 2) isotropic tilt covariance of a 1-sigma angle per axis (radians)."""
    if not math.isfinite(sigma_rad) or sigma_rad < 0:
        raise CameraError(f"a gravity sigma must be a finite angle >= 0, got {sigma_rad!r}")
    return np.eye(2) * sigma_rad * sigma_rad


@dataclass(frozen=True)
class Provenance:
    """Sources of a photo's camera and gravity.

    Attributes:
        camera: one of ``CAMERA_SOURCES``.
        gravity: one of ``GRAVITY_SOURCES``.
        gravity_cov: (2, 2) tilt covariance, rad^2 (pitch, roll axes).
        notes: what was ignored or assumed, one sentence each (EXIF problems, "level
            assumed: ...").
        estimate: when gravity was looked for in the image (source "image", or "level"
            because the image could not tell): the ``vanishing.GravityEstimate`` itself,
            whose segments and lines the photo's hypotheses reuse
            (``photo.hypothesize_estimated``); else None.
    """

    camera: str = "input"
    gravity: str = "input"
    gravity_cov: np.ndarray = field(
        default_factory=lambda: tilt_cov(math.radians(INPUT_GRAVITY_SIGMA_DEG)))
    notes: tuple[str, ...] = ()
    estimate: object = field(default=None, compare=False, repr=False)

    def __post_init__(self) -> None:
        if self.camera not in CAMERA_SOURCES:
            raise CameraError(f"camera source {self.camera!r} is not one of {CAMERA_SOURCES}")
        if self.gravity not in GRAVITY_SOURCES:
            raise CameraError(f"gravity source {self.gravity!r} is not one of {GRAVITY_SOURCES}")
        c = np.asarray(self.gravity_cov, float)
        if c.shape != (2, 2) or not np.all(np.isfinite(c)):
            raise CameraError(f"gravity_cov must be a finite 2x2 matrix, got {self.gravity_cov!r}")
        object.__setattr__(self, "gravity_cov", c)
        object.__setattr__(self, "notes", tuple(self.notes))

    @property
    def gravity_sigma(self) -> float:
        """RMS 1-sigma of gravity's tilt per axis, radians."""
        return float(math.sqrt(max(np.trace(self.gravity_cov), 0.0) / 2.0))

    @property
    def gravity_kind(self) -> str:
        """What gravity's error is like, for results built on it (a plan's sigmas):
        "exact": given and taken as it is, at a 1-sigma no worse than a phone held still's
        (``INPUT_GRAVITY_SIGMA_DEG``: a dataset's, a tripod's); "sensor": given by a sensor
        with a larger 1-sigma, or refined with the photo's lines (source "input+image");
        "image": from the photo's lines alone, or level assumed."""
        if self.gravity in ("image", "level"):
            return "image"
        if (self.gravity == "input"
                and self.gravity_sigma <= math.radians(INPUT_GRAVITY_SIGMA_DEG) + 1e-12):
            return "exact"
        return "sensor"

    @property
    def unsensed_sigma(self) -> float | None:
        """The 1-sigma (radians) a motion checks a gravity no sensor gave against the other
        photo's (``motion.pair_gravity``): ``gravity_sigma`` when it came from the image,
        infinite when level was assumed (no evidence at all); None when given."""
        return {"image": self.gravity_sigma, "level": math.inf}.get(self.gravity)

    @property
    def unsensed_alternatives(self) -> tuple:
        """((3,) vector, ...): the other vertical directions the image supports nearly as
        well, when gravity came from the image (``estimate.alternatives``); else ()."""
        if self.gravity != "image" or self.estimate is None:
            return ()
        return tuple(np.asarray(g, float) for g, _ in self.estimate.alternatives)
