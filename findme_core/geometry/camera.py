"""Pinhole camera with an optional gravity direction that defines its level frame.

Conventions (DESIGN.md, findme-eval README):

* Camera frame: OpenCV, x right, y down, z forward. Pixel (u, v) = (column, row) with the
  origin at the centre of the top-left pixel. No distortion.
* ``gravity`` is the unit vector of gravity (pointing down) in camera coordinates; a level
  camera has (0, 1, 0).
* Level frame: same origin; y = gravity (down); z = the optical axis projected on the
  horizontal plane; x = y x z (right). ``R_level_from_cam`` has these axes as rows, so
  ``p_level = R_level_from_cam @ p_cam``. The floor is the plane y_level = h.
* pitch = asin(g_z) (> 0 looking down); roll = atan2(g_x, g_y) (> 0: right side lower).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from findme_core.errors import CameraError

#: Field of view assumed when a photo comes with no intrinsics at all: a typical phone main
#: camera (26 mm equivalent lens, landscape), degrees.
DEFAULT_HFOV_DEG = 65.0

#: Below this |cos| between gravity and the optical axis the camera is looking straight
#: down or up and "forward" (the level frame's z) is undefined.
_MIN_FORWARD_NORM = 1e-6


def _as_gravity(gravity) -> np.ndarray:
    g = np.asarray((0.0, 1.0, 0.0) if gravity is None else gravity, dtype=float).reshape(-1)
    if g.shape != (3,) or not np.all(np.isfinite(g)):
        raise CameraError(f"gravity must be 3 finite numbers, got {gravity!r}")
    n = float(np.linalg.norm(g))
    if n < 1e-9:
        raise CameraError(f"gravity must not be the zero vector, got {gravity!r}")
    return g / n


@dataclass(frozen=True)
class Camera:
    """Intrinsics (pixels), image size and gravity of one photo.

    Attributes:
        fx, fy: focal lengths in pixels (> 0).
        cx, cy: principal point in pixels (top-left pixel centre = (0, 0)).
        width, height: image size in pixels.
        gravity: (3,) unit gravity in camera coordinates; level camera (0, 1, 0).
    """

    fx: float
    fy: float
    cx: float
    cy: float
    width: int
    height: int
    gravity: np.ndarray = field(default_factory=lambda: np.array([0.0, 1.0, 0.0]))

    def __post_init__(self) -> None:
        for name in ("fx", "fy", "cx", "cy"):
            val = getattr(self, name)
            if not isinstance(val, (int, float, np.floating, np.integer)) or not math.isfinite(val):
                raise CameraError(f"{name} must be a finite number, got {val!r}")
        if self.fx <= 0 or self.fy <= 0:
            raise CameraError(f"focal lengths must be positive, got fx={self.fx}, fy={self.fy}")
        if int(self.width) < 2 or int(self.height) < 2:
            raise CameraError(f"image size must be at least 2x2, got {self.width}x{self.height}")
        g = _as_gravity(self.gravity)
        object.__setattr__(self, "gravity", g)
        object.__setattr__(self, "width", int(self.width))
        object.__setattr__(self, "height", int(self.height))
        fwd = np.array([0.0, 0.0, 1.0]) - g[2] * g
        if np.linalg.norm(fwd) < _MIN_FORWARD_NORM:
            raise CameraError(
                f"gravity {g.round(4).tolist()} is along the optical axis: the camera looks "
                "straight down or up, so it has no horizontal forward direction")
        z = fwd / np.linalg.norm(fwd)
        R = np.stack([np.cross(g, z), g, z])
        R.setflags(write=False)
        object.__setattr__(self, "_R", R)

    # ------------------------------------------------------------------ constructors
    @classmethod
    def from_hfov(cls, hfov_deg: float, width: int, height: int, gravity=None) -> "Camera":
        """Square pixels, principal point at the image centre, horizontal FOV in degrees."""
        if not (0.0 < float(hfov_deg) < 180.0):
            raise CameraError(f"horizontal field of view must be in (0, 180) degrees, got {hfov_deg}")
        f = (width / 2.0) / math.tan(math.radians(hfov_deg) / 2.0)
        return cls(f, f, (width - 1) / 2.0, (height - 1) / 2.0, width, height, gravity)

    def with_gravity(self, gravity) -> "Camera":
        """The same intrinsics with another gravity vector (normalised once, as the
        constructor does: the same vector gives the same camera either way)."""
        return Camera(self.fx, self.fy, self.cx, self.cy, self.width, self.height, gravity)

    def scaled(self, s: float) -> "Camera":
        """The camera of the image resized by factor ``s`` (pixel-centre convention kept)."""
        return Camera(self.fx * s, self.fy * s, (self.cx + 0.5) * s - 0.5,
                      (self.cy + 0.5) * s - 0.5, round(self.width * s), round(self.height * s),
                      self.gravity)

    # ------------------------------------------------------------------ matrices
    @property
    def K(self) -> np.ndarray:
        """(3, 3) intrinsic matrix."""
        return np.array([[self.fx, 0.0, self.cx], [0.0, self.fy, self.cy], [0.0, 0.0, 1.0]])

    @property
    def K_inv(self) -> np.ndarray:
        return np.array([[1.0 / self.fx, 0.0, -self.cx / self.fx],
                         [0.0, 1.0 / self.fy, -self.cy / self.fy], [0.0, 0.0, 1.0]])

    @property
    def R_level_from_cam(self) -> np.ndarray:
        """(3, 3) rotation with the level axes (x_l, y_l, z_l) as rows, in camera coords
        (read-only; computed once)."""
        return self._R

    @property
    def pitch_deg(self) -> float:
        return math.degrees(math.asin(float(np.clip(self.gravity[2], -1.0, 1.0))))

    @property
    def roll_deg(self) -> float:
        return math.degrees(math.atan2(self.gravity[0], self.gravity[1]))

    @property
    def is_level(self) -> bool:
        return bool(np.allclose(self.gravity, (0.0, 1.0, 0.0), atol=1e-9))

    # ------------------------------------------------------------------ rays and projection
    def rays_cam(self, pixels) -> np.ndarray:
        """(N, 2) pixels -> (N, 3) ray directions in the camera frame with z = 1."""
        p = np.asarray(pixels, dtype=float).reshape(-1, 2)
        return np.column_stack([(p[:, 0] - self.cx) / self.fx, (p[:, 1] - self.cy) / self.fy,
                                np.ones(len(p))])

    def rays_level(self, pixels) -> np.ndarray:
        """(N, 2) pixels -> (N, 3) ray directions in the level frame (not normalised)."""
        return self.rays_cam(pixels) @ self.R_level_from_cam.T

    def project_cam(self, points_cam) -> tuple[np.ndarray, np.ndarray]:
        """(N, 3) camera-frame points -> ((N, 2) pixels, (N,) bool in front of the camera)."""
        P = np.asarray(points_cam, dtype=float).reshape(-1, 3)
        z = P[:, 2]
        front = z > 1e-9
        zs = np.where(front, z, 1.0)
        uv = np.column_stack([self.fx * P[:, 0] / zs + self.cx, self.fy * P[:, 1] / zs + self.cy])
        return uv, front

    def project_level(self, points_level) -> tuple[np.ndarray, np.ndarray]:
        """(N, 3) level-frame points -> ((N, 2) pixels, (N,) bool in front of the camera)."""
        P = np.asarray(points_level, dtype=float).reshape(-1, 3)
        return self.project_cam(P @ self.R_level_from_cam)

    # ------------------------------------------------------------------ image lines
    def horizon_line(self) -> np.ndarray:
        """(3,) homogeneous image line l of the horizon, scaled so that l . (u, v, 1) is the
        level-frame y component of the pixel's ray (z = 1 ray): > 0 below the horizon."""
        return self.K_inv.T @ self.gravity

    def below_horizon(self, pixels, margin: float = 0.0) -> np.ndarray:
        """(N,) bool: the pixel's ray points down by more than ``margin`` (ray y / |ray|)."""
        r = self.rays_level(pixels)
        # |r| as np.linalg.norm(r, axis=1) sums it, (x^2 + y^2) + z^2, without its
        # reduction over an axis of 3
        r2 = r * r
        return r[:, 1] > margin * np.sqrt(r2[:, 0] + r2[:, 1] + r2[:, 2])

    def vertical_vanishing_point(self) -> np.ndarray:
        """(3,) homogeneous image point where 3D vertical lines meet (K @ gravity)."""
        return self.K @ self.gravity

    def up_direction(self, pixels) -> np.ndarray:
        """(N, 2) unit image direction of 'up' (against gravity) at each pixel."""
        p = np.asarray(pixels, dtype=float).reshape(-1, 2)
        vp = self.vertical_vanishing_point()
        if abs(vp[2]) < 1e-12:  # vertical lines are parallel in the image
            d = -np.tile(vp[:2], (len(p), 1))
        else:
            vpi = vp[:2] / vp[2]
            d = p - vpi if vp[2] > 0 else vpi - p
            # the VP below the image (looking down, vp[2] > 0): up points away from it
        n = np.linalg.norm(d, axis=1, keepdims=True)
        return d / np.maximum(n, 1e-12)
