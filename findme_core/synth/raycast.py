"""Ray casting and shading of synthetic rooms (``room``) for ``render``: the nearest hit of
each ray, its surface normal, and its shaded colour from the room's seeded textures.

Frames and units as in ``render``: world frame Y down along gravity, floor ``Y = 0``;
metres. Labels: 0 floor, 1 ceiling, 10 + i wall on edge i, 50 + j box j, 255 nothing hit.
Pure functions of their arguments: no I/O, clocks or global random state.
"""

from __future__ import annotations

import functools
import math

import numpy as np

from findme_core.synth import textures as tx
from findme_core.synth.room import Room, _yaw_rot

FLOOR, CEILING, WALL_BASE, BOX_BASE, NO_HIT = 0, 1, 10, 50, 255
_EPS_T = 1e-9
#: Shading: albedo * (A + (1 - A) * (0.5 + 0.5 n.L)) / (1 + F * distance), a wrapped
#: Lambert term (so the walls facing away from the light still differ) with light direction
#: L (toward the light, world frame), ambient A and distance falloff F (per metre).
_LIGHT = np.array([0.55, -0.70, 0.30]) / np.linalg.norm([0.55, -0.70, 0.30])
_AMBIENT, _FALLOFF = 0.5, 0.03


# ---------------------------------------------------------------------------- ray casting
def cast(room: Room, C: np.ndarray, D: np.ndarray):
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


def normals(room: Room, label: np.ndarray, axis: np.ndarray, D: np.ndarray) -> np.ndarray:
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
def surfaces(room: Room, seed: int) -> "_Surfaces":
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


def shade(room, surf, C, D, t, label, axis, pix_angle) -> np.ndarray:
    """(N, 3) float32 BGR radiance in [0, 255]-ish for the hits."""
    n = len(t)
    P = C + t[:, None] * D
    dnorm = np.linalg.norm(D, axis=1)
    dist = t * dnorm
    nrm = normals(room, label, axis, D)
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
