"""3D scene of one photo under a chosen boundary: the floor plane and the walls on it.

Frames: pixels (u, v); rays and points in the camera's level frame (y down along gravity,
floor at y = h) inside, camera frame (OpenCV) at the interface. Metres.

* Floor point (paper eq. 2, P = h (x/y, 1, 1/y) for a level camera's normalised pixel
  (x, y)); generalised by gravity: P_level = (h / r_y) r for the level ray r of the pixel.
* Wall (eqs. 3-4): the vertical plane through the floor line of a boundary segment. The
  segment's image vertices are lifted to the floor (eq. 2), giving a 2D line in the level
  x-z plane; a wall pixel's 3D point is its ray scaled to meet that plane.

Each boundary segment covers an interval of azimuth (angle of the horizontal ray,
atan2(x, z)). A tapped pixel's azimuth selects its segment; it is on the floor if its ray
meets the floor before the wall, else on the wall. OPEN segments (floor continues past the
image) have floor but no known wall; NONE segments (no floor in view) have neither.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .camera import Camera
from .errors import GeometryError, HypothesisError
from .search import SegKind

_PARALLEL = 1e-9


@dataclass(frozen=True)
class Located:
    """3D position of one tapped pixel.

    Attributes:
        pixel: (u, v).
        surface: "floor" or "wall", None when there is no answer.
        xyz: (3,) camera-frame point in metres, None when there is no answer.
        sigma_m: 1-sigma radius of the point in metres: the root sum of squares of
            ``sigma_parts`` ("boundary": the boundary off by one pixel, "height": the camera
            height off by its sigma, "pixel": the tap off by one pixel).
        error: why there is no answer, else None.
    """

    pixel: tuple[float, float]
    surface: str | None
    xyz: np.ndarray | None
    sigma_m: float | None = None
    sigma_parts: dict | None = None
    error: str | None = None


class Scene:
    """Floor and walls of one photo under one hypothesis.

    Args:
        camera: intrinsics and gravity.
        height: camera height above the floor, metres (> 0); 1.0 gives results up to scale.
        polyline: (M, 2) boundary vertices in pixels, u non-decreasing.
        kinds: (M - 1,) SegKind per segment (default: all WALL).
        height_sigma: 1-sigma error of ``height`` in metres.
        boundary_sigma_px: boundary error used for the uncertainty, pixels.
    """

    def __init__(self, camera: Camera, height: float, polyline, kinds=None,
                 height_sigma: float = 0.03, boundary_sigma_px: float = 1.0):
        if not np.isfinite(height) or height <= 0:
            raise GeometryError(f"camera height must be a positive number of metres, got {height!r}")
        poly = np.asarray(polyline, float).reshape(-1, 2)
        if len(poly) < 2 or not np.all(np.isfinite(poly)):
            raise HypothesisError(f"a boundary needs at least 2 finite vertices, got {poly.tolist()}")
        kinds = np.full(len(poly) - 1, SegKind.WALL) if kinds is None else np.asarray(kinds, int)
        if len(kinds) != len(poly) - 1:
            raise HypothesisError(f"{len(kinds)} segment kinds for {len(poly)} vertices")
        self.camera, self.height, self.polyline, self.kinds = camera, float(height), poly, kinds
        self.height_sigma, self.boundary_sigma_px = float(height_sigma), float(boundary_sigma_px)
        self._pieces = self._build(poly)
        shifted = poly + np.array([0.0, boundary_sigma_px])
        self._pieces_shifted = self._build(shifted)

    def _build(self, poly):
        """Pieces: (az0, az1, kind, normal (2,), offset) with n . (x, z) = offset on the wall."""
        cam, R = self.camera, self.camera.R_level_from_cam
        r = cam.rays_cam(poly) @ R.T
        az = np.arctan2(r[:, 0], r[:, 2])
        pieces = []
        for s, kind in enumerate(self.kinds):
            if kind == SegKind.STEP:
                continue
            a0, a1 = az[s], az[s + 1]
            normal, offset = np.zeros(2), 0.0
            if kind == SegKind.WALL:
                if r[s, 1] <= 0 or r[s + 1, 1] <= 0:
                    raise HypothesisError(
                        f"boundary segment {s} from {poly[s].round(1).tolist()} to "
                        f"{poly[s + 1].round(1).tolist()} reaches the horizon: not a floor line")
                q0 = self.height / r[s, 1] * r[s, [0, 2]]   # eq. 2 on each vertex
                q1 = self.height / r[s + 1, 1] * r[s + 1, [0, 2]]
                d = q1 - q0
                if np.hypot(*d) < 1e-9:
                    continue
                normal = np.array([-d[1], d[0]]) / np.hypot(*d)
                offset = float(normal @ q0)
            pieces.append((min(a0, a1), max(a0, a1), int(kind), normal, offset))
        if not pieces:
            raise HypothesisError("the boundary has no floor or wall segment")
        return pieces

    # ------------------------------------------------------------------ queries
    def _piece(self, pieces, az):
        for p in pieces:
            if p[0] <= az <= p[1]:
                return p
        # outside every interval: the nearest end piece (walls extend past the image)
        return min(pieces, key=lambda p: min(abs(az - p[0]), abs(az - p[1])))

    def _point_level(self, pieces, ray):
        """Level-frame point and surface of one level ray under ``pieces``."""
        az = np.arctan2(ray[0], ray[2])
        p = self._piece(pieces, az)
        t_floor = self.height / ray[1] if ray[1] > 0 else np.inf
        t_wall = np.inf
        if p[2] == SegKind.WALL:
            den = float(p[3] @ ray[[0, 2]])
            if abs(den) > _PARALLEL:
                t = p[4] / den
                if t > 0:
                    t_wall = t
                elif not np.isfinite(t_floor):
                    raise GeometryError("the wall's plane lies behind the camera in this "
                                        "direction: the point would be behind the camera")
            elif not np.isfinite(t_floor):
                raise GeometryError("the pixel's ray runs parallel to the wall: it never meets it")
        elif p[2] == SegKind.NONE:
            raise GeometryError("no floor is visible in this direction under the chosen boundary, "
                                "so the wall's distance is unknown")
        if t_floor <= t_wall:
            if not np.isfinite(t_floor):
                raise GeometryError("the pixel is at or above the horizon, so it is not on the floor, "
                                    "and no wall is known in its direction")
            return t_floor * ray, "floor"
        return t_wall * ray, "wall"

    def locate(self, pixels) -> list[Located]:
        """3D of each (u, v) pixel (N, 2); failures are reported per point, not raised."""
        cam = self.camera
        R = cam.R_level_from_cam
        out = []
        for u, v in np.asarray(pixels, float).reshape(-1, 2):
            if not (np.isfinite(u) and np.isfinite(v)):
                out.append(Located((u, v), None, None, error=f"pixel ({u}, {v}) is not finite"))
                continue
            if not (-0.5 <= u <= cam.width - 0.5 and -0.5 <= v <= cam.height - 0.5):
                out.append(Located((u, v), None, None, error=(
                    f"pixel ({u:g}, {v:g}) is outside the {cam.width}x{cam.height} image")))
                continue
            ray = cam.rays_level([(u, v)])[0]
            try:
                P, surface = self._point_level(self._pieces, ray)
            except GeometryError as e:
                out.append(Located((u, v), None, None, error=str(e)))
                continue
            parts = {"height": float(np.linalg.norm(P)) * self.height_sigma / self.height}
            parts["boundary"] = self._moved(self._pieces_shifted, ray, P, surface)
            dp = []
            for du, dv in ((1, 0), (0, 1)):
                r2 = cam.rays_level([(u + du, v + dv)])[0]
                dp.append(self._moved(self._pieces, r2, P, surface))
            parts["pixel"] = float(np.hypot(*dp))
            sigma = float(np.sqrt(sum(x * x for x in parts.values())))
            out.append(Located((u, v), surface, R.T @ P, sigma, parts))
        return out

    def _moved(self, pieces, ray, P, surface) -> float:
        """How far the point moves (m) when recomputed with other pieces or another ray,
        keeping its surface; inf if it has no answer there."""
        try:
            Q, s2 = self._point_level(pieces, ray)
        except GeometryError:
            return float("inf")
        if s2 != surface and surface == "floor":
            t = self.height / ray[1] if ray[1] > 0 else np.inf
            Q = t * ray
        return float(np.linalg.norm(Q - P))

    def floor_point(self, pixel) -> np.ndarray:
        """(3,) camera-frame floor point of a pixel (eq. 2), whatever the walls.

        Raises:
            GeometryError: the pixel is at or above the horizon.
        """
        ray = self.camera.rays_level([pixel])[0]
        if ray[1] <= 1e-12:
            raise GeometryError(f"pixel {tuple(np.round(pixel, 2))} is at or above the horizon: "
                                "its ray never meets the floor")
        return self.camera.R_level_from_cam.T @ (self.height / ray[1] * ray)


def distances(points: list[Located], height: float, height_sigma: float):
    """Distances between consecutive located points (metres) and their 1-sigma.

    Height errors scale every point alike, so that part of a distance's sigma is
    d * height_sigma / height; boundary and pixel parts are taken as independent.

    Returns:
        list of (distance | None, sigma | None, error | None), len(points) - 1 entries.
    """
    out = []
    for a, b in zip(points[:-1], points[1:]):
        if a.xyz is None or b.xyz is None:
            out.append((None, None, "an end point has no 3D position"))
            continue
        d = float(np.linalg.norm(b.xyz - a.xyz))
        s = np.sqrt((d * height_sigma / height) ** 2
                    + a.sigma_parts["boundary"] ** 2 + b.sigma_parts["boundary"] ** 2
                    + a.sigma_parts["pixel"] ** 2 + b.sigma_parts["pixel"] ** 2)
        out.append((d, float(s), None))
    return out
