"""Synthetic photos of rooms (``room``) with exact ground truth, by vectorised ray casting.

``Box``, ``Room``, ``Pose``, ``planar_motion`` and ``relative_transform`` are re-exported
from ``room`` so ``from findme_core.synth import ...`` gives the whole toolkit.

Frames and units (metres, degrees in names ending ``_deg``):

* World (room) frame: Y down along gravity, floor ``Y = 0``, ceiling
  ``Y = -ceiling_height``. The floor polygon lists vertices ``(X, Z)``; wall ``i`` is the
  vertical quad over edge ``i`` (vertex ``i`` to ``i + 1``, cyclic).
* Camera frame: OpenCV (x right, y down, z forward); pixel ``(u, v)`` = (column, row) with
  the origin at the centre of the top-left pixel.
* :class:`Pose`: centre ``(x, -height, z)``; heading ``yaw_deg`` (forward
  ``(sin yaw, 0, cos yaw)``, > 0 turns right toward +X), ``pitch_deg`` (> 0 looking down,
  about camera x) and ``roll_deg`` (> 0 right side lower, about camera z). Then
  ``gravity_cam`` has ``pitch = asin(g_z)`` and ``roll = atan2(g_x, g_y)``, matching
  :class:`findme_core.geometry.camera.Camera`, whose level frame is the pose's yaw-only frame.

Labels: 0 floor, 1 ceiling, 10 + i wall on edge i, 50 + j box j, 255 nothing hit.
Pure functions of their arguments: no I/O, clocks or global random state.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import cv2
import numpy as np

from findme_core.synth import textures as tx
from findme_core.geometry.camera import Camera
from findme_core.errors import GeometryError, InputError
from findme_core.synth.room import Box, Pose, Room, _yaw_rot, planar_motion, relative_transform  # noqa: F401

FLOOR, CEILING, WALL_BASE, BOX_BASE, NO_HIT = 0, 1, 10, 50, 255
_EPS_T = 1e-9
#: Shading: albedo * (A + (1 - A) * (0.5 + 0.5 n.L)) / (1 + F * distance), a wrapped
#: Lambert term (so the walls facing away from the light still differ) with light direction
#: L (toward the light, world frame), ambient A and distance falloff F (per metre).
_LIGHT = np.array([0.55, -0.70, 0.30]) / np.linalg.norm([0.55, -0.70, 0.30])
_AMBIENT, _FALLOFF = 0.5, 0.03


# ---------------------------------------------------------------------------- ray casting
def _cast(room: Room, C: np.ndarray, D: np.ndarray):
    """Nearest positive hit of rays C + t D (world, D (N, 3) not normalised).

    Returns t (N,) (inf if none), label (N,) uint8 and box_axis (N,) int8 (local slab axis
    0/1/2 of a box hit, else -1). Floor and ceiling are infinite planes: with the camera
    inside the prism a ray leaves the room through a wall before reaching the floor plane
    outside the polygon, so the nearest hit is exact for non-convex rooms too."""
    n = len(D)
    dx, dy, dz = D[:, 0], D[:, 1], D[:, 2]
    t = np.full(n, np.inf)
    label = np.full(n, NO_HIT, np.uint8)
    axis = np.full(n, -1, np.int8)
    with np.errstate(divide="ignore", invalid="ignore"):
        tf = np.where(dy > 0, -C[1] / dy, np.inf)
        tc = np.where(dy < 0, (-room.ceiling_height - C[1]) / dy, np.inf)
        label[tf < np.inf] = FLOOR
        t = np.minimum(tf, t)
        m = tc < t
        t[m], label[m] = tc[m], CEILING
        for i in range(room.n_walls):
            (ax, az), (bx, bz) = room.wall_segment(i)
            ex, ez, wx, wz = bx - ax, bz - az, ax - C[0], az - C[2]
            den = dx * ez - dz * ex
            tw = (wx * ez - wz * ex) / den
            s = (wx * dz - wz * dx) / den
            m = (tw > _EPS_T) & (s >= 0) & (s <= 1) & (tw < t)
            t[m], label[m] = tw[m], WALL_BASE + i
        for j, box in enumerate(room.boxes):
            ox, oz = box.to_local(C[0] - box.x, C[2] - box.z)
            lx, lz = box.to_local(dx, dz)
            tnear, tfar = np.full(n, -np.inf), np.full(n, np.inf)
            ax_j = np.zeros(n, np.int8)
            for k, (o, d, half_lo, half_hi) in enumerate(
                    ((ox, lx, -box.width / 2, box.width / 2), (C[1], dy, -box.height, 0.0),
                     (oz, lz, -box.depth / 2, box.depth / 2))):
                t1, t2 = (half_lo - o) / d, (half_hi - o) / d
                lo = np.minimum(t1, t2)
                ax_j[lo > tnear] = k
                tnear, tfar = np.maximum(tnear, lo), np.minimum(tfar, np.maximum(t1, t2))
            m = (tnear <= tfar) & (tnear > _EPS_T) & (tnear < t)
            t[m], label[m], axis[m] = tnear[m], BOX_BASE + j, ax_j[m]
    return t, label, axis


def _normals(room: Room, label: np.ndarray, axis: np.ndarray, D: np.ndarray) -> np.ndarray:
    """(N, 3) world unit normals facing the viewer (walls: inward; boxes: outward)."""
    table = np.zeros((256, 3))
    table[FLOOR], table[CEILING] = (0.0, -1.0, 0.0), (0.0, 1.0, 0.0)
    for i in range(room.n_walls):
        table[WALL_BASE + i] = room.inward_normal(i)
    nrm = table[label]
    for j, box in enumerate(room.boxes):
        m = np.flatnonzero(label == BOX_BASE + j)
        ax = _yaw_rot(box.yaw_deg)[axis[m]]  # local axes in world; row 1 is world Y
        nrm[m] = -np.sign(np.einsum("ij,ij->i", D[m], ax))[:, None] * ax
    return nrm


@functools.lru_cache(maxsize=4)
def _surfaces(room: Room, seed: int) -> "_Surfaces":
    """Cached per (room identity, seed): rooms are immutable and the textures read-only."""
    return _Surfaces(room, seed)


class _Surfaces:
    """Seeded textures of one room: textures are functions of (room, seed) only."""

    def __init__(self, room: Room, seed: int):
        P = room.floor_polygon
        bbox = (*P.min(axis=0), *P.max(axis=0))
        rng = np.random.default_rng
        self.floor = tx.floor_texture(rng([seed, 0]), bbox, room.floor_style)
        self.ceiling = tx.ceiling_texture(rng([seed, 1]), bbox)
        paint = tx.paint_colour(rng([seed, 2]))
        self.walls = [tx.wall_texture(rng([seed, 3, i]),
                                      float(np.linalg.norm(np.diff(room.wall_segment(i), axis=0))),
                                      room.ceiling_height, paint, room.baseboard_height)
                      for i in range(room.n_walls)]
        self.boxes = [tx.box_colour(rng([seed, 4, j])) for j in range(len(room.boxes))]


def _shade(room, surf, C, D, t, label, axis, pix_angle) -> np.ndarray:
    """(N, 3) float32 BGR radiance in [0, 255]-ish for the hits."""
    n = len(t)
    P = C + t[:, None] * D
    dnorm = np.linalg.norm(D, axis=1)
    dist = t * dnorm
    nrm = _normals(room, label, axis, D)
    cos_inc = np.abs(np.einsum("ij,ij->i", nrm, D)) / dnorm
    foot = dist * pix_angle / np.sqrt(np.maximum(cos_inc, 0.05))
    alb = np.zeros((n, 3), np.float32)
    for lab, tex, a, b in ((FLOOR, surf.floor, P[:, 0], P[:, 2]),
                           (CEILING, surf.ceiling, P[:, 0], P[:, 2])):
        m = np.flatnonzero(label == lab)
        alb[m] = tex.sample(a[m], b[m], foot[m])
    for i in range(room.n_walls):
        m = np.flatnonzero(label == WALL_BASE + i)
        (ax, az), (bx, bz) = room.wall_segment(i)
        e = np.array([bx - ax, bz - az]) / math.hypot(bx - ax, bz - az)
        s = (P[m, 0] - ax) * e[0] + (P[m, 2] - az) * e[1]
        alb[m] = surf.walls[i].sample(s, -P[m, 1], foot[m])
    for j, box in enumerate(room.boxes):
        m = np.flatnonzero(label == BOX_BASE + j)
        qx, qz = box.to_local(P[m, 0] - box.x, P[m, 2] - box.z)
        q = np.stack([qx, P[m, 1] + box.height / 2, qz], axis=1)
        half = np.array([box.width, box.height, box.depth]) / 2
        gap = half - np.abs(q)
        gap[np.arange(len(m)), axis[m]] = np.inf  # the face's own axis
        edge = 1.0 - 0.45 * np.exp(-(gap.min(axis=1) / 0.01) ** 2)
        alb[m] = surf.boxes[j] * edge[:, None].astype(np.float32)
    lam = _AMBIENT + (1 - _AMBIENT) * (0.5 + 0.5 * (nrm @ _LIGHT))
    light = lam / (1.0 + _FALLOFF * dist)
    return alb * (255.0 * light)[:, None].astype(np.float32)


# ---------------------------------------------------------------------------- rendering
@dataclass(frozen=True, eq=False)
class View:
    """One rendered photo and its exact ground truth.

    Attributes:
        image: (H, W, 3) uint8 BGR.
        labels: (H, W) uint8 label of each pixel centre's first hit (module docstring).
        points_cam: (H, W, 3) float32 camera-frame point (metres) of each pixel centre's
            first hit (NaN where nothing is hit).
        camera: intrinsics, size and gravity (``pose.gravity_cam``).
        camera_height: metres above the floor.
        boundary_v: W entries: smallest row v labelled floor in column u, or None.
        room, pose: the scene that was rendered.
    """

    image: np.ndarray
    labels: np.ndarray
    points_cam: np.ndarray
    camera: Camera
    camera_height: float
    boundary_v: list
    room: Room
    pose: Pose

    def ground_truth_boundary_polyline(self) -> np.ndarray:
        """(M, 2) float (u, v): the exact ground-wall boundary, u ascending over [0, W-1].

        Definition: in image column u (the whole image-plane line, so v may fall outside
        [0, H-1]) the boundary is the smallest v where the visible floor begins, i.e.
        where a projected scene edge has a non-floor hit 1e-4 px above and a floor hit
        1e-4 px below. The edges are the floor edges of walls and boxes (the ground-wall
        line proper) and the vertical wall/box edges (where floor appears past an
        occluding corner); v is NaN in columns without one. Computed analytically per
        column (no label map), sampled at every integer u plus the u of each projected
        floor corner in the image, so linear interpolation is exact except across the
        one-column jumps at occlusions. Hence ``boundary_v[u] == max(0, floor(v) + 1)``
        wherever that row is in the image (unless, with v < 0, a box hides the floor
        between v and row 0).
        """
        return _boundary_polyline(self.room, self.pose, self.camera)


def _camera(width, height, hfov_deg, intrinsics, gravity) -> Camera:
    if intrinsics is not None:
        if hfov_deg is not None:
            raise InputError("give hfov_deg or intrinsics, not both")
        k = np.asarray(intrinsics, dtype=float)
        fx, fy, cx, cy = (k[0, 0], k[1, 1], k[0, 2], k[1, 2]) if k.shape == (3, 3) else k.reshape(4)
        return Camera(float(fx), float(fy), float(cx), float(cy), width, height, gravity)
    return Camera.from_hfov(65.0 if hfov_deg is None else hfov_deg, width, height, gravity)


def _pixel_rays(cam: Camera, us: np.ndarray, vs: np.ndarray) -> np.ndarray:
    """(len(vs), len(us), 3) camera-frame rays (z = 1) through pixels (u, v)."""
    d = np.empty((len(vs), len(us), 3))
    d[..., 0] = ((us - cam.cx) / cam.fx)[None, :]
    d[..., 1] = ((vs - cam.cy) / cam.fy)[:, None]
    d[..., 2] = 1.0
    return d


def _check_pose(room: Room, pose: Pose) -> None:
    if not 0 < pose.height < room.ceiling_height:
        raise GeometryError(f"camera height {pose.height} m must be inside (0, "
                            f"{room.ceiling_height}) m")
    if not room.contains(pose.x, pose.z):
        raise GeometryError(f"camera ({pose.x}, {pose.z}) is outside the floor polygon")
    for box in room.boxes:
        lx, lz = box.to_local(pose.x - box.x, pose.z - box.z)
        if abs(lx) <= box.width / 2 and abs(lz) <= box.depth / 2 and pose.height <= box.height:
            raise GeometryError(f"camera ({pose.x}, {pose.z}, h={pose.height}) is inside {box}")


def render(room: Room, pose: Pose, width: int = 640, height: int = 480,
           hfov_deg: float | None = None, intrinsics=None, seed: int = 0,
           supersample: int = 2, noise_sigma: float = 2.0,
           noise_seed: int | None = None) -> View:
    """Render ``room`` seen from ``pose``.

    Args:
        width, height: image size in pixels.
        hfov_deg: horizontal field of view (square pixels, centred principal point);
            default 65 when ``intrinsics`` is None.
        intrinsics: (fx, fy, cx, cy) pixels or a (3, 3) K; exclusive with hfov_deg.
        seed: seeds the textures (a function of room and seed only, so two views of one
            room with one seed see the same world-anchored surfaces).
        supersample: s x s colour samples per pixel, area-averaged (labels and points are
            always exact at pixel centres).
        noise_sigma: std of the Gaussian pixel noise (grey levels).
        noise_seed: seed of that noise; default derives from ``seed`` and the pose, so two
            views of one scene get independent noise.
    """
    if int(supersample) != supersample or not 1 <= supersample <= 8:
        raise InputError(f"supersample must be an integer in 1..8, got {supersample}")
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
        raise InputError(f"seed must be a non-negative integer, got {seed!r}")
    if not noise_sigma >= 0:
        raise InputError(f"noise_sigma must be >= 0, got {noise_sigma}")
    _check_pose(room, pose)
    s = int(supersample)
    R, C = pose.R_cam_from_world, pose.centre_world
    cam = _camera(width, height, hfov_deg, intrinsics, pose.gravity_cam)
    W, H = cam.width, cam.height
    surf = _surfaces(room, int(seed))

    d_cam = _pixel_rays(cam, np.arange(W, dtype=float), np.arange(H, dtype=float))
    D = d_cam.reshape(-1, 3) @ R  # rows: R^T d
    t, label, axis = _cast(room, C, D)
    pts = np.where(np.isfinite(t)[:, None], t[:, None] * d_cam.reshape(-1, 3), np.nan)
    labels = label.reshape(H, W)

    if s > 1:
        sub = (np.arange(s, dtype=float) + 0.5) / s - 0.5
        us = (np.arange(W)[:, None] + sub).reshape(-1)
        vs = (np.arange(H)[:, None] + sub).reshape(-1)
        Ds = _pixel_rays(cam, us, vs).reshape(-1, 3) @ R
        ts, ls, axs = _cast(room, C, Ds)
    else:
        Ds, ts, ls, axs = D, t, label, axis
    pix_angle = 1.0 / (math.sqrt(cam.fx * cam.fy) * s)
    col = _shade(room, surf, C, Ds, ts, ls, axs, pix_angle)
    img = col.reshape(H * s, W * s, 3)
    if s > 1:  # area average of each s x s block
        img = cv2.resize(img, (W, H), interpolation=cv2.INTER_AREA)
    if noise_sigma > 0:
        if noise_seed is None:
            key = np.array([pose.x, pose.z, pose.height, pose.yaw_deg, pose.pitch_deg,
                            pose.roll_deg], dtype=np.float64).view(np.uint64)
            rng = np.random.default_rng([int(seed) & 0xFFFFFFFF, 7, *map(int, key)])
        else:
            rng = np.random.default_rng([int(noise_seed) & 0xFFFFFFFF, 8])
        img = img + rng.normal(0.0, noise_sigma, img.shape).astype(np.float32)
    image = np.clip(np.rint(img), 0, 255).astype(np.uint8)

    is_floor = labels == FLOOR
    first = np.argmax(is_floor, axis=0)
    bv = [int(first[u]) if is_floor[first[u], u] else None for u in range(W)]
    return View(image, labels, pts.reshape(H, W, 3).astype(np.float32), cam,
                float(pose.height), bv, room, pose)


def _boundary_polyline(room: Room, pose: Pose, cam: Camera) -> np.ndarray:
    R, C = pose.R_cam_from_world, pose.centre_world
    # candidate 3D segments: floor edges of walls and boxes, and the vertical edges at the
    # polygon vertices and box corners (a floor seen past an occluding edge starts there)
    base = [room.wall_segment(i) for i in range(room.n_walls)]
    tops = [(p, room.ceiling_height) for p in room.floor_polygon]
    for box in room.boxes:
        c = box.corners_xz()
        base += [np.stack([c[k], c[(k + 1) % 4]]) for k in range(4)]
        tops += [(p, box.height) for p in c]
    A = np.array([(e[0, 0], 0.0, e[0, 1]) for e in base] + [(p[0], 0.0, p[1]) for p, _ in tops])
    B = np.array([(e[1, 0], 0.0, e[1, 1]) for e in base] + [(p[0], -h, p[1]) for p, h in tops])
    a, b = (A - C) @ R.T, (B - A) @ R.T  # camera frame: P(s) = a + s b, s in [0, 1]
    # extra columns at the projected corners
    front = a[:, 2] > 1e-9
    uc = cam.fx * a[front, 0] / a[front, 2] + cam.cx
    cols = np.unique(np.concatenate([np.arange(cam.width, dtype=float),
                                     uc[(uc >= 0) & (uc <= cam.width - 1)]]))
    u = cols[:, None]
    num = cam.fx * a[:, 0] + (cam.cx - u) * a[:, 2]
    den = cam.fx * b[:, 0] + (cam.cx - u) * b[:, 2]
    with np.errstate(divide="ignore", invalid="ignore"):
        sp = -num / den
        z = a[:, 2] + sp * b[:, 2]
        v = cam.fy * (a[:, 1] + sp * b[:, 1]) / z + cam.cy
    ok = (np.abs(den) > 1e-12) & (sp >= -1e-9) & (sp <= 1 + 1e-9) & (z > 1e-9) & np.isfinite(v)
    iu, iseg = np.nonzero(ok)
    cu, cv = cols[iu], v[iu, iseg]
    delta = 1e-4
    probe_u = np.concatenate([cu, cu])
    probe_v = np.concatenate([cv - delta, cv + delta])
    d = np.stack([(probe_u - cam.cx) / cam.fx, (probe_v - cam.cy) / cam.fy,
                  np.ones(len(probe_u))], axis=1) @ R
    _, lab, _ = _cast(room, C, d)
    n = len(cu)
    good = (lab[:n] != FLOOR) & (lab[n:] == FLOOR)
    best = np.full(len(cols), np.inf)
    np.minimum.at(best, iu[good], cv[good])
    best[~np.isfinite(best)] = np.nan
    return np.column_stack([cols, best])
