"""The room's layout seen by one photo, on the floor plane of its level frame.

A boundary hypothesis (pixel polyline + segment kinds, ``search.SegKind``), the camera
(intrinsics + gravity) and the camera height h give, in the photo's LEVEL frame (x right,
z forward, y down; metres; the floor is y = h, so everything here is (x, z)):

* walls: the floor lines of the WALL segments (paper eq. 2 on their image end points), each
  from its left to its right end in the image, with what bounds each end (``End``): a
  corner (two walls meet), an occluding vertical edge (the near surface of a step ends
  there), or nothing seen (the wall goes on past the image border or behind an occluder);
* a scan: the boundary sampled across the image, like a 2-D range scan on the floor: per
  azimuth (atan2(x, z), radians) the horizontal distance to the wall base (WALL), a lower
  bound (OPEN: the floor goes on past the top border) or an upper bound (NONE: no floor
  seen down to the bottom border), with its 1-sigma;
The room's orientation from the photo's lines (no floor needed) is ``orientation``; how two
photos' layouts agree under a motion is ``register``. Pure numpy / OpenCV; no I/O.
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import IntEnum
from functools import cached_property

import cv2
import numpy as np

from findme_core.errors import HypothesisError
from findme_core.geometry import ties
from findme_core.geometry.camera import Camera
from findme_core.geometry.scan import Scan
from findme_core.single.search import SegKind

#: ``SegKind`` values as plain ints, for comparing ``Layout.kind`` arrays (here and in the
#: modules that read layouts): numpy compares an array with an IntEnum member through Python
KIND_WALL, KIND_STEP = int(SegKind.WALL), int(SegKind.STEP)
KIND_OPEN, KIND_NONE = int(SegKind.OPEN), int(SegKind.NONE)


class End(IntEnum):
    """What bounds a wall at one end in the photo."""

    OPEN = 0     # nothing seen: the wall goes on past the border or behind an occluder
    CORNER = 1   # another wall meets it at a floor corner
    EDGE = 2     # an occluding vertical edge: the (nearer) surface ends there


@dataclass(frozen=True)
class LayoutParams:
    """Sampling and uncertainty of a layout.

    Attributes:
        step_px: the scan samples the boundary every ``step_px`` image columns.
        boundary_px: 1-sigma of the boundary position, pixels (hypothesis and snapping).
        gravity_deg: 1-sigma of the gravity direction, degrees.
        height_rel: relative 1-sigma of the camera height.
        merge_deg: consecutive WALL segments closer than this in direction are one wall.
        simplify_px: a run of WALL segments is first reduced to the vertices that keep it
            within this many pixels (Douglas-Peucker).
    """

    step_px: float = 6.0
    boundary_px: float = 1.5
    gravity_deg: float = 0.5
    height_rel: float = 0.02
    merge_deg: float = 6.0
    simplify_px: float = 1.0


@dataclass(frozen=True)
class Layout:
    """What one photo under one hypothesis shows of the room, on the floor of its level frame.

    Attributes:
        walls: (K, 2, 2) wall base segments [[x0, z0], [x1, z1]], metres, left end first.
        ends: (K, 2) ``End`` of each wall's left and right end.
        azimuth: (S,) scan directions, radians (atan2(x, z), > 0 to the right), ascending.
        range: (S,) horizontal distance to the boundary in each direction, metres (inf: no
            bound).
        kind: (S,) SegKind of each sample: WALL (the wall base is there), OPEN (floor seen
            at least that far), NONE (no floor seen: something stands nearer).
        sigma: (S,) 1-sigma of ``range``, metres.
        wall: (S,) index of the wall of a WALL sample, else -1.
        height: camera height above the floor, metres.
        rank: the hypothesis' rank (1 = best), 0 when not from a ranked list.
    """

    walls: np.ndarray
    ends: np.ndarray
    azimuth: np.ndarray
    range: np.ndarray
    kind: np.ndarray
    sigma: np.ndarray
    wall: np.ndarray
    height: float
    rank: int = 0

    @cached_property
    def points(self) -> np.ndarray:
        """(S, 2) floor points (x, z) of the samples (inf where the range is unbounded)."""
        return self.range[:, None] * np.column_stack([np.sin(self.azimuth), np.cos(self.azimuth)])

    @cached_property
    def spacing(self) -> float:
        """Median azimuth step between samples, radians (0 with fewer than 2)."""
        return float(np.median(np.diff(self.azimuth))) if len(self.azimuth) > 1 else 0.0

    @cached_property
    def scan(self) -> Scan:
        """Its samples looked up by azimuth (``scan.Scan``; at least 2 samples)."""
        return Scan(self)

    @cached_property
    def normals(self) -> np.ndarray:
        """(K, 2) unit normal of each wall, pointing to the camera's side."""
        d = self.walls[:, 1] - self.walls[:, 0]
        n = np.column_stack([-d[:, 1], d[:, 0]]) / np.maximum(np.hypot(*d.T), 1e-12)[:, None]
        flip = np.einsum("ij,ij->i", n, self.walls[:, 0]) > 0   # the camera is at the origin
        return np.where(flip[:, None], -n, n)

    @property
    def corners(self) -> np.ndarray:
        """(C, 2) floor points where two walls meet (the right end of the left wall)."""
        return self.walls[self.ends[:, 1] == End.CORNER, 1].reshape(-1, 2)

    @property
    def n_wall_samples(self) -> int:
        return int(np.count_nonzero(self.kind == KIND_WALL))


def floor_xz(camera: Camera, h: float, pixels) -> tuple[np.ndarray, np.ndarray]:
    """Level rays (N, 3) of (N, 2) pixels and where they meet the horizontal plane ``h``
    metres below the camera, (N, 2) (x, z) (eq. 2 for the floor; NaN at or above the
    horizon)."""
    r = camera.rays_level(pixels)
    with np.errstate(divide="ignore", invalid="ignore"):
        s = np.where(r[:, 1] > 1e-9, h / r[:, 1], np.nan)
    return r, s[:, None] * r[:, [0, 2]]


def from_hypothesis(camera: Camera, height: float, polyline, kinds=None, rank: int = 0,
                    params: LayoutParams = LayoutParams()) -> Layout:
    """Layout of one photo under a boundary hypothesis.

    Args:
        camera: intrinsics and gravity of the photo.
        height: camera height above the floor, metres (> 0).
        polyline: (M, 2) boundary vertices in pixels, u non-decreasing from 0 to W - 1.
        kinds: (M - 1,) SegKind per segment (default: all WALL).

    Raises:
        HypothesisError: fewer than 2 vertices, non-finite values, or a WALL vertex at or
            above the horizon (not a floor line).
    """
    poly = np.asarray(polyline, float).reshape(-1, 2)
    if len(poly) < 2 or not np.isfinite(poly).all():
        raise HypothesisError(f"a boundary needs at least 2 finite vertices, got {poly.tolist()}")
    kinds = np.full(len(poly) - 1, SegKind.WALL) if kinds is None else np.asarray(kinds, int)
    if len(kinds) != len(poly) - 1:
        raise HypothesisError(f"{len(kinds)} segment kinds for {len(poly)} vertices")
    if not (np.isfinite(height) and height > 0):
        raise HypothesisError(f"camera height must be a positive number of metres, got {height!r}")
    h = float(height)
    wpoly, wkinds = _simplify(poly, kinds, params.simplify_px)
    _, q = floor_xz(camera, h, wpoly)
    walls, ends = _walls(wpoly, wkinds, q, params)
    return Layout(walls, ends, *_scan(camera, h, poly, kinds, walls, params), h, int(rank))


def _simplify(poly, kinds, eps: float):
    """The polyline with each run of consecutive WALL segments reduced by Douglas-Peucker
    (``eps`` pixels; a boundary traced column by column becomes its few straight lines)."""
    kinds = np.asarray(kinds).tolist()   # Python ints: a numpy int against SegKind is slow
    out_p, out_k, s = [poly[0]], [], 0
    while s < len(kinds):
        if kinds[s] != SegKind.WALL:
            out_p.append(poly[s + 1])
            out_k.append(int(kinds[s]))
            s += 1
            continue
        e = s
        while e < len(kinds) and kinds[e] == SegKind.WALL:
            e += 1
        run = poly[s:e + 1]
        if len(run) > 2:
            keep = cv2.approxPolyDP(run.astype(np.float32).reshape(-1, 1, 2), eps, False)
            idx = [int(np.argmin(np.abs(run - k).sum(1))) for k in keep.reshape(-1, 2)]
            run = run[sorted(set(idx) | {0, len(run) - 1})]
        out_p.extend(run[1:])
        out_k.extend([SegKind.WALL] * (len(run) - 1))
        s = e
    return np.array(out_p), np.array(out_k, int)


def _walls(poly, kinds, q, params: LayoutParams):
    """Wall segments (K, 2, 2) and their end kinds (K, 2) from the WALL segments, merging
    nearly collinear neighbours."""
    walls, ends = [], []
    kinds = np.asarray(kinds).tolist()   # Python ints: a numpy int against SegKind is slow
    for s, k in enumerate(kinds):
        if k != SegKind.WALL:
            continue
        if not np.isfinite(q[s]).all() or not np.isfinite(q[s + 1]).all():
            raise HypothesisError(f"boundary segment {s} from {poly[s].round(1).tolist()} to "
                                  f"{poly[s + 1].round(1).tolist()} reaches the horizon: not a "
                                  "floor line")
        if np.hypot(*(q[s + 1] - q[s])) < 1e-6:
            continue
        ends.append([_end(poly, kinds, s, -1), _end(poly, kinds, s, +1)])
        walls.append([q[s], q[s + 1]])
    walls, ends = np.array(walls, float).reshape(-1, 2, 2), np.array(ends, int).reshape(-1, 2)
    keep = np.ones(len(walls), bool)
    for k in range(1, len(walls)):   # merge a corner between two nearly collinear walls
        j = np.flatnonzero(keep[:k])[-1]
        if ends[j, 1] != End.CORNER or not np.allclose(walls[j, 1], walls[k, 0]):
            continue
        d0, d1 = walls[j, 1] - walls[j, 0], walls[k, 1] - walls[k, 0]
        ang = abs(np.arctan2(d0[0] * d1[1] - d0[1] * d1[0], d0 @ d1))
        if ang < np.radians(params.merge_deg):
            walls[j, 1], ends[j, 1] = walls[k, 1], ends[k, 1]
            keep[k] = False
    return walls[keep], ends[keep]


def _end(poly, kinds, s: int, side: int) -> int:
    """End kind of WALL segment s on its left (side -1) or right (+1)."""
    j = s + side   # the neighbouring segment
    if j < 0 or j >= len(kinds):
        return End.OPEN
    if kinds[j] == SegKind.WALL:
        return End.CORNER
    if kinds[j] == SegKind.STEP:   # the lower side of a step (larger v) is the nearer surface
        mine, other = (poly[s], poly[s - 1]) if side < 0 else (poly[s + 1], poly[s + 2])
        return End.EDGE if mine[1] > other[1] else End.OPEN
    return End.OPEN


def _scan(camera: Camera, h: float, poly, kinds, walls, params: LayoutParams):
    """Samples of the boundary every ``step_px`` columns: azimuth, range, kind, sigma and
    wall index (see ``Layout``)."""
    W, H = camera.width, camera.height
    u = np.arange(0.0, W - 1.0 + 1e-9, params.step_px)
    seg = np.clip(np.searchsorted(poly[1:, 0], u, side="left"), 0, len(kinds) - 1)
    kind = kinds[seg].copy()
    step = kind == KIND_STEP   # a sample falling on a step's 0.5-px width: skip it
    v = np.interp(u, poly[:, 0], poly[:, 1])
    rows = np.where(kind == KIND_OPEN, -0.5, np.where(kind == KIND_NONE, H - 0.5, v))
    r, q = floor_xz(camera, h, np.column_stack([u, rows]))
    az = np.arctan2(r[:, 0], r[:, 2])
    rng = np.hypot(q[:, 0], q[:, 1])
    rng = np.where(np.isfinite(rng), rng, np.inf)
    # 1-sigma: the depression angle off by the boundary and gravity errors moves the floor
    # point by (h^2 + d^2) / h per radian; the height error scales it
    dep = np.hypot(params.boundary_px / np.hypot(camera.fx, camera.fy) * np.sqrt(2),
                   np.radians(params.gravity_deg))
    sigma = np.hypot((h * h + rng ** 2) / h * dep, params.height_rel * rng)
    wall = np.full(len(u), -1)
    if len(walls):
        w = np.flatnonzero(kind == KIND_WALL)
        pts = q[w]
        a, b = walls[:, 0], walls[:, 1]
        d = b - a
        t = np.clip(np.einsum("skj,kj->sk", pts[:, None] - a[None], d)
                    / np.maximum(np.einsum("kj,kj->k", d, d), 1e-12), 0, 1)
        dist = np.linalg.norm(pts[:, None] - (a[None] + t[..., None] * d[None]), axis=2)
        wall[w] = ties.argmin(dist, axis=1)   # a sample at a corner: the first wall
    keep = ~step & ((kind != KIND_WALL) | np.isfinite(rng))
    o = np.argsort(az[keep], kind="stable")
    return az[keep][o], rng[keep][o], kind[keep][o], sigma[keep][o], wall[keep][o]


def turned(L: Layout, yaw: float) -> Layout:
    """``L`` seen from a frame the photo is turned ``yaw`` in (radians, > 0 right): a floor
    point p becomes R(yaw) p (``register.rot2``), an azimuth a becomes a + yaw (wrapped to
    (-pi, pi]; the samples are re-sorted). The camera stays at the origin, so the ranges,
    kinds and sigmas are unchanged."""
    c, s = np.cos(yaw), np.sin(yaw)
    R = np.array([[c, s], [-s, c]])
    az = np.angle(np.exp(1j * (L.azimuth + yaw)))
    o = np.argsort(az, kind="stable")
    return Layout(L.walls @ R.T, L.ends, az[o], L.range[o], L.kind[o], L.sigma[o], L.wall[o],
                  L.height, L.rank)


def merged(layouts, yaws) -> Layout:
    """One layout of the photos a camera turned through at one place (a spot): each layout
    (``turned`` by its yaw in the first photo's frame) contributes its walls and samples.
    Azimuths that several photos see are sampled by each (the scan is then denser there).

    Raises:
        HypothesisError: no layout, or the photos' camera heights differ (not one place).
    """
    if not len(layouts):
        raise HypothesisError("no layout to merge")
    hs = [L.height for L in layouts]
    if max(hs) - min(hs) > 1e-6:
        raise HypothesisError(f"photos at one place share a camera height, not {hs}")
    parts = [turned(L, y) for L, y in zip(layouts, yaws)]
    offs = np.cumsum([0] + [len(p.walls) for p in parts[:-1]])
    az = np.concatenate([p.azimuth for p in parts])
    o = np.argsort(az, kind="stable")
    cat = lambda k: np.concatenate([getattr(p, k) for p in parts])  # noqa: E731
    wall = np.concatenate([np.where(p.wall >= 0, p.wall + k, -1) for p, k in zip(parts, offs)])
    return Layout(np.concatenate([p.walls for p in parts]).reshape(-1, 2, 2),
                  np.concatenate([p.ends for p in parts]).reshape(-1, 2), az[o], cat("range")[o],
                  cat("kind")[o], cat("sigma")[o], wall[o], hs[0], layouts[0].rank)
