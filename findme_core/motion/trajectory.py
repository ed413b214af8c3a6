"""Localisation over a session: chain the planar motions of successive photos into poses,
and write / read them in the TUM trajectory format (evo, TUM RGB-D tools).

Frames and units:

* Session frame = the LEVEL frame of the session's first photo (camera 0): origin at its
  camera centre, y down along gravity, z its optical axis projected on the horizontal
  plane, x right (DESIGN.md). Metres, radians.
* Pose k = pose of photo k's level frame in the session frame: X_0 = R_y(yaw_k) X_k + p_k,
  R_y(yaw) = [[c, 0, s], [0, 1, 0], [-s, 0, c]], p_k = (x, y, z); yaw > 0 turned right.
* A pair motion (A, B) (``motion.PlanarMotion``) is exactly the pose of B in A's level
  frame, so poses chain by composition (paper step 5, "chaining motions localises the
  user"): pose_{k+1} = pose_k o motion_{k,k+1}, i.e. yaw_{k+1} = yaw_k + yaw_m and
  p_{k+1} = p_k + R_y(yaw_k) (x_m, dy_m, z_m).
* TUM lines "timestamp tx ty tz qx qy qz qw": timestamp in seconds (written with 9 decimals
  from integer nanoseconds, so they round-trip exactly), (tx, ty, tz) = p_k, and the unit
  quaternion of R_y(yaw_k) = (0, sin(yaw / 2), 0, cos(yaw / 2)): the rotation from the
  photo's level frame to the session frame (world_from_camera, as evo expects).

Uncertainty: each pose carries a 3x3 covariance of (x, z, yaw), propagated to first
order through the compositions (it grows along the session, as dead reckoning does).

Pure: numbers in, numbers / text out (the caller writes the file).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from findme_core.errors import InputError

TUM_HEADER = ("# findme trajectory (TUM format): timestamp[s] tx ty tz qx qy qz qw\n"
              "# pose of each photo's LEVEL frame (y down along gravity, z forward, x right) in\n"
              "# the session frame = level frame of the first photo; metres; q = world_from_camera\n")


@dataclass(frozen=True)
class PlanarPose:
    """Pose of a photo's level frame in the session frame.

    Attributes:
        x, y, z: position of the camera centre, metres (y down; from the dy of the motions).
        yaw: heading, radians (> 0 turned right of photo 0).
        cov: (3, 3) covariance of (x, z, yaw), m^2 / m rad / rad^2.
    """

    x: float
    y: float
    z: float
    yaw: float
    cov: np.ndarray = field(default_factory=lambda: np.zeros((3, 3)), compare=False)

    def matrix(self) -> np.ndarray:
        """(4, 4) homogeneous transform session <- photo (level frames)."""
        c, s = math.cos(self.yaw), math.sin(self.yaw)
        return np.array([[c, 0.0, s, self.x], [0.0, 1.0, 0.0, self.y],
                         [-s, 0.0, c, self.z], [0.0, 0.0, 0.0, 1.0]])

    def quaternion(self) -> tuple[float, float, float, float]:
        """(qx, qy, qz, qw) of R_y(yaw), qw >= 0."""
        h = _wrap(self.yaw) / 2.0
        return 0.0, math.sin(h), 0.0, math.cos(h)


def _wrap(a: float) -> float:
    return math.atan2(math.sin(a), math.cos(a))


def compose(pose: PlanarPose, x: float, z: float, yaw: float, dy: float = 0.0,
            cov=None) -> PlanarPose:
    """``pose`` followed by a relative motion (x, z, yaw, dy) given in pose's level frame,
    with 3x3 covariance ``cov`` of (x, z, yaw) (None: exact). First-order propagation:
    C' = Ja C Ja^T + Jb Cm Jb^T."""
    vals = (x, z, yaw, dy)
    if not all(math.isfinite(v) for v in vals):
        raise InputError(f"a motion must be finite numbers, got {vals}")
    c, s = math.cos(pose.yaw), math.sin(pose.yaw)
    dx, dz = c * x + s * z, -s * x + c * z                     # R_y(yaw_k) (x, z)
    Ja = np.array([[1.0, 0.0, -s * x + c * z], [0.0, 1.0, -c * x - s * z], [0.0, 0.0, 1.0]])
    Jb = np.array([[c, s, 0.0], [-s, c, 0.0], [0.0, 0.0, 1.0]])
    cm = np.zeros((3, 3)) if cov is None else np.asarray(cov, float).reshape(3, 3)
    return PlanarPose(pose.x + dx, pose.y + dy, pose.z + dz, _wrap(pose.yaw + yaw),
                      Ja @ pose.cov @ Ja.T + Jb @ cm @ Jb.T)


def chain(motions, start: PlanarPose | None = None) -> list[PlanarPose]:
    """Poses of photos 0..n from the n motions (k, k+1) of successive photos.

    Args:
        motions: sequence of ``motion.PlanarMotion`` (x, z, yaw, dy and sigma_* are used;
            the sigmas as independent) or of (x, z, yaw) / (x, z, yaw, dy) tuples (exact).
        start: pose of photo 0 (default: the origin of the session frame).

    Returns:
        n + 1 poses, the first being ``start``.
    """
    poses = [start or PlanarPose(0.0, 0.0, 0.0, 0.0)]
    for m in motions:
        if hasattr(m, "yaw"):
            cov = np.diag([m.sigma_x, m.sigma_z, m.sigma_yaw]) ** 2
            poses.append(compose(poses[-1], m.x, m.z, m.yaw, m.dy, cov))
        else:
            vals = tuple(float(v) for v in m)
            if len(vals) not in (3, 4):
                raise InputError(f"a motion is (x, z, yaw) or (x, z, yaw, dy), got {m!r}")
            poses.append(compose(poses[-1], *vals))
    return poses


def to_tum(poses, timestamps_ns) -> str:
    """The TUM trajectory text (``TUM_HEADER`` comment, then one line per pose)."""
    if len(poses) != len(timestamps_ns):
        raise InputError(f"{len(poses)} poses but {len(timestamps_ns)} timestamps")
    lines = [TUM_HEADER]
    for p, ns in zip(poses, timestamps_ns):
        ns = int(ns)
        if ns < 0:
            raise InputError(f"timestamps must be non-negative nanoseconds, got {ns}")
        q = p.quaternion()
        lines.append(f"{ns // 1_000_000_000}.{ns % 1_000_000_000:09d} {p.x:.9f} {p.y:.9f} "
                     f"{p.z:.9f} {q[0]:.9f} {q[1]:.9f} {q[2]:.9f} {q[3]:.9f}\n")
    return "".join(lines)


def from_tum(text: str) -> tuple[list[int], list[PlanarPose]]:
    """Parse TUM text back to (timestamps in ns, poses). Rotations must be about y (the
    format of ``to_tum``); comments and blank lines are skipped.

    Raises:
        InputError: a line is not 8 numbers or its rotation is not about the vertical.
    """
    stamps, poses = [], []
    for k, line in enumerate(text.splitlines(), 1):
        line = line.strip()
        if not line or line.startswith("#"):
            continue
        parts = line.split()
        try:
            vals = [float(v) for v in parts]
        except ValueError:
            vals = []
        if len(vals) != 8 or not all(math.isfinite(v) for v in vals):
            raise InputError(f"TUM line {k} must be 8 numbers "
                             f"(timestamp tx ty tz qx qy qz qw), got {line!r}")
        sec, _, frac = parts[0].partition(".")
        stamps.append(int(sec) * 1_000_000_000 + int((frac + "000000000")[:9] or 0))
        qx, qy, qz, qw = vals[4:]
        if abs(qx) > 1e-6 or abs(qz) > 1e-6 or abs(math.hypot(qy, qw) - 1.0) > 1e-6:
            raise InputError(f"TUM line {k}: the rotation is not a unit rotation about the "
                             "vertical (y) axis")
        poses.append(PlanarPose(vals[1], vals[2], vals[3], _wrap(2.0 * math.atan2(qy, qw))))
    return stamps, poses
