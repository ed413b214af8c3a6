"""Synthetic rooms and camera poses with exact ground truth (the scene description; the
renderer is ``synth``).

Frames and units (metres, degrees in names ending ``_deg``):

* World (room) frame: Y down along gravity, floor ``Y = 0``, ceiling
  ``Y = -ceiling_height``. The floor polygon lists vertices ``(X, Z)``; wall ``i`` is the
  vertical quad over edge ``i`` (vertex ``i`` to ``i + 1``, cyclic).
* :class:`Pose`: centre ``(x, -height, z)``; heading ``yaw_deg`` (forward
  ``(sin yaw, 0, cos yaw)``, > 0 turns right toward +X), ``pitch_deg`` (> 0 looking down,
  about camera x) and ``roll_deg`` (> 0 right side lower, about camera z). Then
  ``gravity_cam`` has ``pitch = asin(g_z)`` and ``roll = atan2(g_x, g_y)``, matching
  :class:`findme_core.geometry.camera.Camera`, whose level frame is the pose's yaw-only frame.
* Planar motion of a pair (A, B): the pose of camera B in A's level frame (x right,
  z forward, yaw > 0 when B is turned right of A), as in the evaluation set.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from findme_core.errors import InputError

def _yaw_rot(yaw_deg: float) -> np.ndarray:
    """(3, 3) rows = the level axes (x right, y down, z forward) in world coordinates."""
    s, c = math.sin(math.radians(yaw_deg)), math.cos(math.radians(yaw_deg))
    return np.array([[c, 0.0, -s], [0.0, 1.0, 0.0], [s, 0.0, c]])


@dataclass(frozen=True)
class Box:
    """Cuboid standing on the floor: centre (x, z), extent ``width`` along its local x
    (world X at yaw 0), ``depth`` along local z, ``height`` up from the floor; turned by
    ``yaw_deg`` like a camera heading (local z = (sin yaw, 0, cos yaw))."""

    x: float
    z: float
    width: float
    depth: float
    height: float
    yaw_deg: float = 0.0

    def __post_init__(self) -> None:
        if min(self.width, self.depth, self.height) <= 0:
            raise InputError(f"box sizes must be positive, got {self}")

    def to_local(self, X: np.ndarray, Z: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """World (X, Z) -> local (x, z) relative to the centre (directions: pass offsets)."""
        R = _yaw_rot(self.yaw_deg)
        return R[0, 0] * X + R[0, 2] * Z, R[2, 0] * X + R[2, 2] * Z

    def corners_xz(self) -> np.ndarray:
        """(4, 2) world (X, Z) of the base corners, in order around the box."""
        R = _yaw_rot(self.yaw_deg)
        hw, hd = self.width / 2, self.depth / 2
        loc = np.array([[-hw, -hd], [hw, -hd], [hw, hd], [-hw, hd]])
        return loc @ R[[0, 2]][:, [0, 2]] + (self.x, self.z)


@dataclass(frozen=True, eq=False)
class Room:
    """Prism room: floor polygon (N, 2) of (X, Z) metres (3..40 vertices, simple, either
    orientation), ``ceiling_height`` metres, optional :class:`Box` es (or 6-tuples
    ``(x, z, width, depth, height, yaw_deg)``), ``floor_style`` "wood" or "carpet" and the
    wall baseboard height (metres)."""

    floor_polygon: np.ndarray
    ceiling_height: float = 2.5
    boxes: tuple = ()
    floor_style: str = "wood"
    baseboard_height: float = 0.08

    def __post_init__(self) -> None:
        P = np.array(self.floor_polygon, dtype=float)
        if P.ndim != 2 or P.shape[1] != 2 or not 3 <= len(P) <= 40 or not np.isfinite(P).all():
            raise InputError(f"floor_polygon must be 3..40 finite (X, Z) vertices, got {P.shape}")
        if abs(_signed_area(P)) < 1e-6 or _self_intersects(P):
            raise InputError("floor_polygon must be a simple polygon with non-zero area")
        if not self.ceiling_height > 0:
            raise InputError(f"ceiling_height must be positive, got {self.ceiling_height}")
        if self.floor_style not in ("wood", "carpet"):
            raise InputError(f"floor_style must be 'wood' or 'carpet', got {self.floor_style!r}")
        boxes = tuple(b if isinstance(b, Box) else Box(*b) for b in self.boxes)
        if len(boxes) > 200:
            raise InputError(f"at most 200 boxes, got {len(boxes)}")
        P.setflags(write=False)
        object.__setattr__(self, "floor_polygon", P)
        object.__setattr__(self, "boxes", boxes)

    @property
    def n_walls(self) -> int:
        return len(self.floor_polygon)

    def wall_segment(self, i: int) -> np.ndarray:
        """(2, 2) (X, Z) of the start and end vertex of wall i."""
        P = self.floor_polygon
        return np.stack([P[i], P[(i + 1) % len(P)]])

    def inward_normal(self, i: int) -> np.ndarray:
        """(3,) unit world normal of wall i pointing into the room."""
        (x0, z0), (x1, z1) = self.wall_segment(i)
        sgn = 1.0 if _signed_area(self.floor_polygon) > 0 else -1.0  # > 0: interior on the left
        n = sgn * np.array([-(z1 - z0), 0.0, x1 - x0])
        return n / np.linalg.norm(n)

    def contains(self, x: float, z: float) -> bool:
        """(x, z) strictly inside the floor polygon (even-odd rule)."""
        P, Q = self.floor_polygon, np.roll(self.floor_polygon, -1, axis=0)
        cross = (P[:, 1] > z) != (Q[:, 1] > z)
        with np.errstate(divide="ignore", invalid="ignore"):
            xs = P[:, 0] + (z - P[:, 1]) * (Q[:, 0] - P[:, 0]) / (Q[:, 1] - P[:, 1])
        return bool(np.count_nonzero(cross & (x < xs)) % 2)

    @classmethod
    def rectangle(cls, width: float = 5.0, depth: float = 4.0, **kw) -> "Room":
        """X in [-width/2, width/2], Z in [-depth/2, depth/2]. Walls: 0 at Z = -depth/2
        (behind a yaw-0 camera), 1 at X = +width/2 (right), 2 at Z = +depth/2 (ahead),
        3 at X = -width/2 (left)."""
        w, d = width / 2, depth / 2
        return cls([(-w, -d), (w, -d), (w, d), (-w, d)], **kw)

    @classmethod
    def l_shape(cls, width: float = 6.0, depth: float = 5.0, notch_width: float = 2.5,
                notch_depth: float = 2.0, **kw) -> "Room":
        """The ``rectangle(width, depth)`` minus its (+X, +Z) corner of
        ``notch_width x notch_depth``; the reflex vertex is 3. The origin stays inside."""
        if not (0 < notch_width < width and 0 < notch_depth < depth):
            raise InputError("the notch must be smaller than the room")
        w, d = width / 2, depth / 2
        room = cls([(-w, -d), (w, -d), (w, d - notch_depth), (w - notch_width, d - notch_depth),
                    (w - notch_width, d), (-w, d)], **kw)
        if not room.contains(0.0, 0.0):
            raise InputError("the notch must leave the origin inside the room")
        return room


def _signed_area(P: np.ndarray) -> float:
    Q = np.roll(P, -1, axis=0)
    return 0.5 * float(np.sum(P[:, 0] * Q[:, 1] - Q[:, 0] * P[:, 1]))


def _self_intersects(P: np.ndarray) -> bool:
    n = len(P)
    if np.any(np.linalg.norm(P - np.roll(P, -1, axis=0), axis=1) < 1e-9):
        return True

    def orient(a, b, c):
        return np.sign((b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0]))
    for i in range(n):
        for j in range(i + 2, n):
            if i == 0 and j == n - 1:
                continue
            a, b, c, d = P[i], P[(i + 1) % n], P[j], P[(j + 1) % n]
            if orient(a, b, c) != orient(a, b, d) and orient(c, d, a) != orient(c, d, b):
                return True
    return False


@dataclass(frozen=True)
class Pose:
    """Camera pose in the room: centre (x, -height, z) metres and yaw/pitch/roll degrees
    (see the module docstring)."""

    x: float
    z: float
    height: float
    yaw_deg: float = 0.0
    pitch_deg: float = 0.0
    roll_deg: float = 0.0

    @property
    def centre_world(self) -> np.ndarray:
        """(3,) camera centre in the world frame."""
        return np.array([self.x, -self.height, self.z], dtype=float)

    @property
    def R_level_from_world(self) -> np.ndarray:
        """(3, 3) world -> level frame (yaw only; y down, z the horizontal heading)."""
        return _yaw_rot(self.yaw_deg)

    @property
    def R_cam_from_world(self) -> np.ndarray:
        """(3, 3) rotation: p_cam = R @ (p_world - centre_world)."""
        p, r = math.radians(self.pitch_deg), math.radians(self.roll_deg)
        R_pitch = np.array([[1.0, 0.0, 0.0], [0.0, math.cos(p), -math.sin(p)],
                            [0.0, math.sin(p), math.cos(p)]])
        R_roll = np.array([[math.cos(r), math.sin(r), 0.0], [-math.sin(r), math.cos(r), 0.0],
                           [0.0, 0.0, 1.0]])
        return R_roll @ R_pitch @ self.R_level_from_world

    @property
    def gravity_cam(self) -> np.ndarray:
        """(3,) unit gravity (world +Y) in camera coordinates."""
        return self.R_cam_from_world[:, 1].copy()


def _wrap_deg(a: float) -> float:
    return float(-((-a + 180.0) % 360.0 - 180.0))


def relative_transform(pose_a: Pose, pose_b: Pose) -> np.ndarray:
    """(4, 4) T_a_from_b: X_a = T @ X_b for homogeneous camera-frame points (metres)."""
    Ra, Rb = pose_a.R_cam_from_world, pose_b.R_cam_from_world
    T = np.eye(4)
    T[:3, :3] = Ra @ Rb.T
    T[:3, 3] = Ra @ (pose_b.centre_world - pose_a.centre_world)
    return T


def planar_motion(pose_a: Pose, pose_b: Pose) -> tuple[float, float, float]:
    """(x_m, z_m, yaw_deg): B's centre in A's level frame (x right, z forward, metres) and
    B's heading relative to A (degrees in (-180, 180], > 0 when B is turned right)."""
    d = pose_a.R_level_from_world @ (pose_b.centre_world - pose_a.centre_world)
    return float(d[0]), float(d[2]), _wrap_deg(pose_b.yaw_deg - pose_a.yaw_deg)
