"""Edge support of candidate boundary lines, tabulated per image column.

The paper scores a hypothesis by the fraction of its length lying on edge pixels. A
hypothesis is a polyline made of pieces of a few infinite lines between their
intersections, so we tabulate, for every candidate line i and image column u, the
cumulative supported arc length ``S[i, u]``, the cumulative in-image arc length
``L[i, u]`` and the cumulative count of columns where the line is outside the image
``O[i, u]``. The support of any piece [u_a, u_b) of line i is then ``S[i, u_b] - S[i, u_a]``:
O(1) per piece, so thousands of polylines are scored in a few milliseconds.

Evidence of one sample p on a line with unit normal n pointing to the floor side:
    edge   = clip(|grad I(p) . n| / tau, 0, 1), zero unless the gradient is within
             ``max_angle_deg`` of n (an edge along the line, not across it);
    floor  = 1 - clip(|I(p + a n) - I(p + b n)| / tau_c, 0, 1), the floor just below the
             line looks like the floor further below (rejects the top edge of a baseboard,
             whose band below differs from the carpet beyond);
    e(p)   = edge * (w_floor * floor + 1 - w_floor).
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np


@dataclass(frozen=True)
class SupportParams:
    tau: float = 12.0            # gradient (grey levels / px) that counts as a full edge
    max_angle_deg: float = 25.0  # gradient direction vs line normal
    tau_c: float = 30.0          # colour difference (L2 over BGR) that counts as different
    near_px: float = 3.0         # a: offset of the "just below" sample
    far_px: float = 12.0         # b: offset of the "further below" sample
    w_floor: float = 0.5         # weight of the floor-continuity factor
    blur_sigma: float = 1.0


def sample_bilinear(arr: np.ndarray, pts: np.ndarray) -> np.ndarray:
    """Bilinear samples of a float32 image ``arr`` ((H, W) or (H, W, C)) at (..., 2) pixel
    positions (border replicated): shape pts.shape[:-1] (+ (C,))."""
    return sample_bilinear_many((arr,), pts)[0]


def sample_bilinear_many(arrs, pts: np.ndarray) -> list:
    """``[sample_bilinear(arr, pts) for arr in arrs]``, the remap maps made once."""
    flat = pts.reshape(-1, 2)
    return sample_bilinear_xy(arrs, flat[:, 0], flat[:, 1], pts.shape[:-1])


def sample_bilinear_xy(arrs, x: np.ndarray, y: np.ndarray, shape=None) -> list:
    """``sample_bilinear_many`` at the pixel positions (x, y) given as two arrays of one
    shape (any; the samples' shape unless ``shape`` is given; + (C,) for (H, W, C))."""
    shape = x.shape if shape is None else shape
    m = x.size
    cols = 1024  # cv2.remap maps must stay under SHRT_MAX columns
    rows = max(1, -(-m // cols))
    mx = np.zeros(rows * cols, np.float32)
    my = np.zeros(rows * cols, np.float32)
    mx[:m], my[:m] = x.reshape(-1), y.reshape(-1)
    mx, my = mx.reshape(rows, cols), my.reshape(rows, cols)
    outs = []
    for arr in arrs:
        out = cv2.remap(arr, mx, my, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)
        if arr.ndim == 3:
            outs.append(out.reshape(rows * cols, -1)[:m].reshape(*shape, -1))
        else:
            outs.append(out.reshape(-1)[:m].reshape(shape))
    return outs


@dataclass(frozen=True)
class SupportTable:
    """Cumulative per-column tables for N lines over an image W columns wide.

    Attributes:
        S: (N, W + 1) cumulative supported arc length (px) before column u.
        L: (N, W + 1) cumulative in-image arc length (px) before column u.
        O: (N, W + 1) cumulative number of columns where the line is outside the image.
        v: (N, W) row of each line at each column (may lie outside the image).
    """

    S: np.ndarray
    L: np.ndarray
    O: np.ndarray
    v: np.ndarray


class EdgeField:
    """Precomputed image derivatives for sampling edge evidence (one per image).

    Args:
        image: (H, W, 3) uint8 BGR.
        color: optional (H, W, 3) float32 image to compare colours in (e.g. Lab; default
            BGR); ``tau_c`` is in its units.
        top_row: derivatives are computed from this row down (e.g. the rows below the
            horizon, where floor lines are); above it they are 0 (no edge).
    """

    def __init__(self, image: np.ndarray, params: SupportParams = SupportParams(),
                 color: np.ndarray | None = None, top_row: int = 0):
        img = image if image.ndim == 3 else cv2.cvtColor(image, cv2.COLOR_GRAY2BGR)
        self.params = params
        self.height, self.width = img.shape[:2]
        self.color = img.astype(np.float32) if color is None else color
        # the blur and Sobel reach ~4 px: start a few rows higher so that rows >= top_row
        # are exactly as on the whole image
        top = int(np.clip(top_row - 8, 0, self.height - 1)) if top_row > 0 else 0
        gray = cv2.GaussianBlur(cv2.cvtColor(img[top:], cv2.COLOR_BGR2GRAY).astype(np.float32),
                                (0, 0), params.blur_sigma)
        # rows above ``top`` are 0 (no edge), the rest are written by Sobel: np.empty, not
        # np.zeros (whose fresh zero pages then fault in one by one as Sobel writes them)
        self.gx = np.empty((self.height, self.width), np.float32)
        self.gy = np.empty((self.height, self.width), np.float32)
        self.gx[:top] = 0.0
        self.gy[:top] = 0.0
        # scale 1/8: the Sobel kernel's weight, exact (a power of two)
        cv2.Sobel(gray, cv2.CV_32F, 1, 0, dst=self.gx[top:], ksize=3, scale=0.125)
        cv2.Sobel(gray, cv2.CV_32F, 0, 1, dst=self.gy[top:], ksize=3, scale=0.125)
        if top:
            self.gx[top:top_row] = 0.0
            self.gy[top:top_row] = 0.0
        self.top_row = max(int(top_row), 0) if top_row > 0 else 0   # derivatives from here down

    def sample(self, arr: np.ndarray, pts: np.ndarray) -> np.ndarray:
        """Bilinear samples of ``arr`` at (M, 2) pixel positions (border replicated)."""
        return sample_bilinear(arr, pts)

    def band_texture(self, rows: np.ndarray, cols: np.ndarray | None = None, offset_px: int = 3,
                     band_px: int = 24) -> np.ndarray:
        """Mean gradient magnitude (grey levels per pixel) in the band of rows
        [row + offset, row + offset + band) below each row: ``rows`` (N, W) at every column,
        or (K,) at the columns ``cols`` (K,); 0 where the band lies outside the image (rows
        above the derivatives add nothing)."""
        r0 = np.clip(np.floor(rows + offset_px), 0, self.height).astype(int)
        r1 = np.clip(r0 + band_px, 0, self.height)
        if r0.size == 0:
            return np.zeros(rows.shape)
        # a summed-area table of the strip of rows the bands cover (rows above the
        # derivatives add nothing)
        lo = max(int(r0.min()), min(self.top_row, self.height))
        hi = int(r1.max())
        if hi <= lo:                  # every band below the image or above the derivatives
            return np.zeros(rows.shape)
        S = cv2.integral(cv2.magnitude(self.gx[lo:hi], self.gy[lo:hi]), sdepth=cv2.CV_64F)
        a, b = np.clip(r0 - lo, 0, hi - lo), np.clip(r1 - lo, 0, hi - lo)
        u = np.broadcast_to(np.arange(self.width), rows.shape) if cols is None else cols
        total = (S[b, u + 1] - S[b, u]) - (S[a, u + 1] - S[a, u])
        return np.where(r1 > r0, total / np.maximum(r1 - r0, 1), 0.0)

    def evidence(self, pts: np.ndarray, normals: np.ndarray) -> np.ndarray:
        """(M,) evidence in [0, 1] of (M, 2) points with (M, 2) unit normals (floor side)."""
        p = self.params
        # one channel at a time: OpenCV remaps one float channel with exact bilinear
        # weights, several channels with weights quantised to 1/32 pixel
        gx, gy = sample_bilinear_many((self.gx, self.gy), pts)   # one pair of maps
        gn = np.abs(gx * normals[:, 0] + gy * normals[:, 1])
        gm = np.sqrt(gx * gx + gy * gy)
        aligned = gn >= np.cos(np.radians(p.max_angle_deg)) * gm
        edge = np.where(aligned, np.clip(gn / p.tau, 0.0, 1.0), 0.0)
        if p.w_floor <= 0:
            return edge
        m = len(pts)
        far = pts + p.far_px * normals
        c = self.sample(self.color, np.concatenate([pts + p.near_px * normals, far]))
        c = c.astype(np.float32)
        d = c[:m] - c[m:]
        # |d|^2 summed as (d0^2 + d1^2) + d2^2 in float32, as (d * d).sum(1) does, without
        # a reduction over an axis of 3 (numpy's slowest case)
        dd = d * d
        floor = 1.0 - np.clip(np.sqrt(dd[:, 0] + dd[:, 1] + dd[:, 2]) / p.tau_c, 0.0, 1.0)
        # where the far sample leaves the image the continuity is unknown: neutral
        inside = (far[:, 1] <= self.height - 1) & (far[:, 0] >= 0) & (far[:, 0] <= self.width - 1)
        floor = np.where(inside, floor, 1.0)
        return edge * (p.w_floor * floor + 1.0 - p.w_floor)


class CannyField(EdgeField):
    """The paper's edge support: a sample counts if it lies on a Canny edge pixel (the edge
    map dilated by one pixel, so a line one pixel off still counts)."""

    def __init__(self, image: np.ndarray, low: int = 50, high: int = 150):
        gray = image if image.ndim == 2 else cv2.cvtColor(image, cv2.COLOR_BGR2GRAY)
        self.height, self.width = gray.shape
        edges = cv2.dilate(cv2.Canny(gray, low, high), np.ones((3, 3), np.uint8))
        self.edges = (edges > 0).astype(np.float32)

    def evidence(self, pts: np.ndarray, normals: np.ndarray) -> np.ndarray:
        u = np.clip(np.round(pts[:, 0]), 0, self.width - 1).astype(int)
        v = np.clip(np.round(pts[:, 1]), 0, self.height - 1).astype(int)
        return self.edges[v, u].astype(float)


def line_rows(coef: np.ndarray, width: int) -> np.ndarray:
    """(N, 3) lines (a, b, c) with b != 0 -> (N, W) row v at each column u = 0..W-1."""
    u = np.arange(width, dtype=float)
    return -(coef[:, :1] * u[None, :] + coef[:, 2:3]) / coef[:, 1:2]


def tabulate(field: EdgeField, coef: np.ndarray, substeps: int = 2) -> SupportTable:
    """Tabulate cumulative support of N non-vertical image lines (``|b| > 0``).

    Each column is split into ``substeps`` sub-columns; a sub-column's arc length is
    ``sqrt(1 + slope^2) / substeps``, so steep lines are weighted by their true length
    and sampled at least every ``1/substeps`` columns (steep lines with more samples along
    the row direction: one per pixel of arc).
    """
    W, H = field.width, field.height
    n = len(coef)
    if n == 0:
        z = np.zeros((0, W + 1))
        return SupportTable(z, z, z, np.zeros((0, W)))
    coef = np.asarray(coef, float)
    slope = -coef[:, 0] / coef[:, 1]                       # dv/du
    ds_col = np.sqrt(1.0 + slope ** 2)                       # arc length per column
    k = np.maximum(substeps, np.ceil(ds_col)).astype(int)    # samples per column, per line
    S = np.zeros((n, W + 1))
    Lc = np.zeros((n, W + 1))
    v = line_rows(coef, W)
    O = np.zeros((n, W + 1))
    O[:, 1:] = np.cumsum((v < -0.5) | (v > H - 0.5), axis=1)
    normals = coef[:, :2]  # b >= 0: points to larger v (down); floor side for floor lines
    # every line's samples at once: line i has W * k[i] samples at u = (j + 0.5) / k[i] - 0.5
    counts = W * k
    li = np.repeat(np.arange(n), counts)
    j = np.arange(counts.sum()) - np.repeat(np.cumsum(counts) - counts, counts)
    u = (j + 0.5) / k[li] - 0.5
    vv = slope[li] * u - (coef[:, 2] / coef[:, 1])[li]
    ins = (vv >= -0.5) & (vv <= H - 0.5)
    if ins.any():
        li, u, vv = li[ins], u[ins], vv[ins]
        e = field.evidence(np.column_stack([u, vv]), normals[li])
        w = (ds_col / k)[li]
        flat = li * W + np.clip(np.round(u), 0, W - 1).astype(int)
        sup = np.bincount(flat, weights=e * w, minlength=n * W).reshape(n, W)
        length = np.bincount(flat, weights=w, minlength=n * W).reshape(n, W)
        S[:, 1:] = np.cumsum(sup, axis=1)
        Lc[:, 1:] = np.cumsum(length, axis=1)
    return SupportTable(S, Lc, O, v)
