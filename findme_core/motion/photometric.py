"""Photometric agreement of two photos under a planar motion: each photo's pixels placed in
3D by its own layout (floor pixels on the floor, wall pixels on the wall base's vertical
line) and looked up in the other photo: evidence that needs no feature match (the
``findme`` estimator, ``estimator``, scores its best candidates with it).

Frames and units (DESIGN.md, ``methods``): X_A = R_y(yaw) X_B + t, t = (x, dy, z) metres, yaw
radians; each photo's level frame has y down and the floor at y = h. The images are compared
after local normalisation (zero mean, unit variance over a small window; a flat region is
~0 there, so blank walls say nothing and an exposure change between the photos does not
matter): a motion's agreement is the correlation of the normalised values of the samples
each photo sees of the other's surfaces (the overlap of what both see), in [-1, 1]. Pure
numpy / OpenCV.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import cv2
import numpy as np

from findme_core.geometry.camera import Camera
from findme_core.single.layout import KIND_WALL, Layout


@dataclass(frozen=True)
class PhotometricParams:
    """Sampling of the comparison.

    Attributes:
        width: the photos are compared at this width, pixels (aspect kept).
        step: every ``step``-th pixel of that thumbnail is a sample, both ways.
        window: side of the normalisation window, thumbnail pixels.
        flat: grey levels: a window whose standard deviation is well below this is flat
            (its normalised values shrink toward 0).
        hidden_m: a sample farther than the other photo's boundary by more than this (plus
            10 % of its distance) is hidden behind the other photo's walls.
    """

    width: int = 80
    step: int = 1
    window: int = 9
    flat: float = 6.0
    hidden_m: float = 0.1


@dataclass(frozen=True)
class Surface:
    """One photo's samples placed in 3D by its layout.

    Attributes:
        camera: the thumbnail's camera; image: (h, w) float32 normalised thumbnail.
        points: (S, 3) level-frame points of the samples, metres (none without a
            layout); values: (S,) their normalised grey values; layout: the layout that
            placed them, or None (the photo is then only looked up, every pixel visible).
    """

    camera: Camera
    image: np.ndarray
    points: np.ndarray
    values: np.ndarray
    layout: Layout | None

    @cached_property
    def homogeneous(self) -> np.ndarray:
        """(4, S) the samples' points as homogeneous columns [x; y; z; 1], metres."""
        return np.vstack([self.points.T, np.ones((1, len(self.points)))])


def normalised(grey: np.ndarray, window: int, flat: float) -> np.ndarray:
    """(H, W) grey -> (H, W) float32 locally normalised: (g - mean) / sqrt(var + flat^2)."""
    g = grey.astype(np.float32)
    k = (window, window)
    mu = cv2.blur(g, k)
    var = np.maximum(cv2.blur(g * g, k) - mu * mu, 0.0)
    return (g - mu) / np.sqrt(var + flat * flat)


def surface(image, camera: Camera, layout: Layout | None,
            params: PhotometricParams = PhotometricParams()) -> Surface:
    """The samples of one photo (``image`` (H, W[, 3]) uint8, the size of ``camera``) on the
    floor and walls of its ``layout``: none without a layout (or one that sees no floor),
    the photo then only serves as the other's lookup."""
    cam = camera.scaled(params.width / camera.width)
    grey = image if image.ndim == 2 else cv2.cvtColor(image, cv2.COLOR_BGR2GRAY)
    small = cv2.resize(grey, (cam.width, cam.height), interpolation=cv2.INTER_AREA)
    return _placed(cam, normalised(small, params.window, params.flat), layout, params)


def replaced(surf: Surface, camera: Camera, layout: Layout | None,
             params: PhotometricParams = PhotometricParams()) -> Surface:
    """``surf``'s photo placed again under another ``camera`` (its gravity corrected, same
    intrinsics) and ``layout``: the thumbnail is reused, not computed again."""
    return _placed(camera.scaled(params.width / camera.width), surf.image, layout, params)


def _placed(cam: Camera, img: np.ndarray, layout: Layout | None,
            params: PhotometricParams) -> Surface:
    """The samples of the normalised thumbnail ``img`` (of camera ``cam``) on ``layout``."""
    if layout is None or len(layout.azimuth) < 2:
        return Surface(cam, img, np.zeros((0, 3)), np.zeros(0, np.float32), None)
    v, u = np.mgrid[params.step // 2:cam.height:params.step, params.step // 2:cam.width:params.step]
    px = np.column_stack([u.ravel(), v.ravel()]).astype(float)
    r = cam.rays_level(px)
    horiz = np.hypot(r[:, 0], r[:, 2])
    j, near = layout.scan.nearest(np.arctan2(r[:, 0], r[:, 2]))
    rng, kind = layout.range[j], layout.kind[j]
    with np.errstate(divide="ignore", invalid="ignore"):
        d_floor = np.where(r[:, 1] > 1e-6, layout.height * horiz / r[:, 1], np.inf)
        floor = near & (d_floor < rng) & np.isfinite(d_floor)
        wall = near & ~floor & (kind == KIND_WALL) & np.isfinite(rng)
        scale = np.where(floor, layout.height / r[:, 1], np.where(wall, rng / horiz, np.nan))
    keep = np.flatnonzero(floor | wall)
    pts = scale[keep, None] * r[keep]
    vals = img[v.ravel()[keep], u.ravel()[keep]]
    return Surface(cam, img, pts, vals, layout)


def _transforms(yaw, t, into_b: bool, R_cam: np.ndarray) -> np.ndarray:
    """(5, C, 4) affine maps of homogeneous src level-frame points to, per motion, the dst
    camera-frame coordinates (rows 0-2) and the dst level-frame x and z (rows 3-4).

    X_A = R_y(yaw) X_B + t: into B, q = R^T X_A - R^T t; into A, q = R X_B + t; the camera
    frame is R_cam^T q (``Camera.R_level_from_cam``)."""
    c, s = np.cos(yaw), np.sin(yaw)
    C = len(yaw)
    A = np.zeros((C, 3, 3))
    A[:, 0, 0] = A[:, 2, 2] = c
    A[:, 1, 1] = 1.0
    A[:, 0, 2], A[:, 2, 0] = (-s, s) if into_b else (s, -s)
    b = -np.einsum("cij,cj->ci", A, t) if into_b else t
    M = np.zeros((5, C, 4))
    M[:3, :, :3] = np.einsum("ki,cij->kcj", R_cam.T, A)
    M[:3, :, 3] = R_cam.T @ b.T
    M[3:, :, :3] = A[:, [0, 2]].transpose(1, 0, 2)
    M[3:, :, 3] = b[:, [0, 2]].T
    return M


def _one_way(src: Surface, dst: Surface, yaw, t, into_b: bool, p: PhotometricParams):
    """Sum of products (C,) and sample counts (C,) of src's samples seen by dst."""
    C = len(yaw)
    if len(src.points) == 0:
        return np.zeros(C), np.zeros(C, int)
    cam = dst.camera
    # one matrix product: every sample under every motion, in dst's camera and level frame
    g = (_transforms(yaw, t, into_b, cam.R_level_from_cam).reshape(5 * C, 4)
         @ src.homogeneous).reshape(5, C, -1)
    z = g[2]
    front = z > 1e-9
    zs = np.where(front, z, 1.0)
    u = np.multiply(cam.fx, g[0])   # fx x / z + cx, in place
    u /= zs
    u += cam.cx
    v = np.multiply(cam.fy, g[1])
    v /= zs
    v += cam.cy
    h, w = dst.image.shape
    seen = front & (u >= 0) & (u <= w - 1) & (v >= 0) & (v <= h - 1)
    if dst.layout is not None:   # not hidden behind dst's walls: the samples seen so far
        L = dst.layout
        i = np.nonzero(seen)
        x, zl = g[3][i], g[4][i]
        j, near = L.scan.nearest(np.arctan2(x, zl))
        bound = L.range * 1.1 + p.hidden_m
        seen[i] = near & (x * x + zl * zl <= (bound * bound)[j])
    # looked up everywhere (cheaper than choosing where); only the seen samples count
    m = cv2.remap(dst.image, u.astype(np.float32), v.astype(np.float32), cv2.INTER_LINEAR,
                  borderMode=cv2.BORDER_CONSTANT, borderValue=0.0)
    prod = np.where(seen, m * src.values[None], 0.0)
    return prod.sum(1), seen.sum(1)


def agreement(sa: Surface | None, sb: Surface | None, yaw, t,
              params: PhotometricParams = PhotometricParams()):
    """Correlation (C,) of the normalised images under C motions (yaw (C,), t (C, 3)) over
    the samples each photo sees of the other's surfaces, both ways, and their count (C,);
    0 where none is seen or a photo has no surface."""
    yaw, t = np.atleast_1d(np.asarray(yaw, float)), np.atleast_2d(np.asarray(t, float))
    if sa is None or sb is None:
        return np.zeros(len(yaw)), np.zeros(len(yaw), int)
    s1, n1 = _one_way(sa, sb, yaw, t, True, params)
    s2, n2 = _one_way(sb, sa, yaw, t, False, params)
    n = n1 + n2
    return np.where(n > 0, (s1 + s2) / np.maximum(n, 1), 0.0), n
