"""Seeded procedural textures for :mod:`findme_core.synth.render`.

Every texture is an albedo image anchored to 2D surface coordinates ``(a, b)`` in metres
(floor/ceiling: ``(X, Z)``; wall: metres along the edge from its first vertex and height
above the floor), so the same surface point has the same albedo in every view. Albedo is
BGR float32 in [0, 1]. Images are mip-mapped and sampled trilinearly so distant surfaces
do not alias. All randomness comes from the ``numpy.random.Generator`` passed in.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numpy as np

#: Width of the 2D maps handed to cv2.remap (it refuses maps wider than SHRT_MAX).
_REMAP_COLS = 1024

#: Largest texture side in texels; bigger surfaces get coarser texels.
_MAX_SIDE = 2048

# BGR albedos in [0, 1].
_PAINTS = ((0.80, 0.84, 0.86), (0.72, 0.80, 0.84), (0.83, 0.80, 0.74), (0.70, 0.78, 0.72),
           (0.78, 0.78, 0.78), (0.66, 0.75, 0.82))
_WOODS = ((0.30, 0.45, 0.62), (0.22, 0.33, 0.48), (0.45, 0.60, 0.72), (0.28, 0.38, 0.50))
_CARPETS = ((0.40, 0.42, 0.45), (0.50, 0.40, 0.33), (0.35, 0.45, 0.52), (0.30, 0.32, 0.30))
_BOXES = ((0.20, 0.28, 0.60), (0.55, 0.35, 0.15), (0.25, 0.50, 0.30), (0.62, 0.60, 0.58),
          (0.18, 0.18, 0.22))


@dataclass(frozen=True)
class Texture:
    """Mip-mapped albedo image anchored to surface coordinates.

    ``levels[0]`` is (rows, cols, 3) float32 BGR in [0, 1]; the centre of texel (r, c) lies
    at ``a = a0 + c * texel``, ``b = b0 + r * texel`` (metres). ``levels[k]`` is the 2x2
    area mean of ``levels[k-1]``. Outside the image the texture is mirrored.
    """

    levels: tuple
    a0: float
    b0: float
    texel: float

    @classmethod
    def from_image(cls, img: np.ndarray, a0: float, b0: float, texel: float,
                   max_levels: int = 6) -> "Texture":
        levels = [np.ascontiguousarray(np.clip(img, 0.0, 1.0), dtype=np.float32)]
        while len(levels) < max_levels and min(levels[-1].shape[:2]) >= 16:
            prev = levels[-1]
            h, w = prev.shape[0] // 2, prev.shape[1] // 2
            levels.append(cv2.resize(prev[:2 * h, :2 * w], (w, h), interpolation=cv2.INTER_AREA))
        return cls(tuple(levels), float(a0), float(b0), float(texel))

    def sample(self, a: np.ndarray, b: np.ndarray, footprint: np.ndarray) -> np.ndarray:
        """(N,) a, b and footprint (metres covered by one sample) -> (N, 3) float32 albedo."""
        n = len(a)
        out = np.empty((n, 3), np.float32)
        if n == 0:
            return out
        c0 = (np.asarray(a, float) - self.a0) / self.texel
        r0 = (np.asarray(b, float) - self.b0) / self.texel
        top = len(self.levels) - 1
        lod = np.clip(np.log2(np.maximum(np.asarray(footprint, float) / self.texel, 1e-9)), 0, top)
        lo = np.minimum(np.floor(lod).astype(np.int64), top)
        frac = (lod - lo).astype(np.float32)[:, None]
        for lvl in np.unique(lo):
            idx = np.flatnonzero(lo == lvl)
            col = _remap(self.levels[lvl], c0[idx], r0[idx], lvl)
            if lvl < top:
                col2 = _remap(self.levels[lvl + 1], c0[idx], r0[idx], lvl + 1)
                col += (col2 - col) * frac[idx]
            out[idx] = col
        return out


def _remap(img: np.ndarray, c0: np.ndarray, r0: np.ndarray, lvl: int) -> np.ndarray:
    """Bilinear samples of mip level ``lvl`` at level-0 texel coordinates -> (N, 3)."""
    scale = 2.0 ** -lvl
    cx = ((c0 + 0.5) * scale - 0.5).astype(np.float32)
    cy = ((r0 + 0.5) * scale - 0.5).astype(np.float32)
    n = len(cx)
    pad = (-n) % _REMAP_COLS
    mx = np.pad(cx, (0, pad)).reshape(-1, _REMAP_COLS)
    my = np.pad(cy, (0, pad)).reshape(-1, _REMAP_COLS)
    res = cv2.remap(img, mx, my, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REFLECT_101)
    return res.reshape(-1, 3)[:n]


def _noise(rng: np.random.Generator, rows: int, cols: int, cell_r: float,
           cell_c: float | None = None) -> np.ndarray:
    """(rows, cols) float32 smooth value noise in about [-1, 1], features ~cell texels."""
    cell_c = cell_r if cell_c is None else cell_c
    gr = max(2, int(math.ceil(rows / cell_r)) + 1)
    gc = max(2, int(math.ceil(cols / cell_c)) + 1)
    grid = rng.random((gr, gc), dtype=np.float32) * 2.0 - 1.0
    return cv2.resize(grid, (cols, rows), interpolation=cv2.INTER_CUBIC)


def _grid(extent_a: float, extent_b: float, texel: float) -> tuple[int, int, float]:
    texel = max(texel, max(extent_a, extent_b) / (_MAX_SIDE - 2))
    return (int(math.ceil(extent_b / texel)) + 2, int(math.ceil(extent_a / texel)) + 2, texel)


def floor_texture(rng: np.random.Generator, bbox, style: str = "wood",
                  texel: float = 0.004) -> Texture:
    """Floor albedo over ``bbox = (xmin, zmin, xmax, zmax)`` (metres), a = X, b = Z.

    ``style`` is ``"wood"`` (planks with seams and grain) or ``"carpet"`` (multi-scale
    tufted noise)."""
    margin = 0.05
    xmin, zmin, xmax, zmax = (float(v) for v in bbox)
    rows, cols, texel = _grid(xmax - xmin + 2 * margin, zmax - zmin + 2 * margin, texel)
    a0, b0 = xmin - margin, zmin - margin
    if style == "carpet":
        base = np.array(_CARPETS[rng.integers(len(_CARPETS))], np.float32)
        g = (0.10 * _noise(rng, rows, cols, 60) + 0.15 * _noise(rng, rows, cols, 12)
             + 0.15 * _noise(rng, rows, cols, 4) + 0.06 * _noise(rng, rows, cols, 1.5))
        # flecks: thresholded noise gives sharp-edged light and dark blobs (1-3 cm)
        light = np.clip((_noise(rng, rows, cols, 5) - 0.55) * 8, 0, 1)
        dark = np.clip((_noise(rng, rows, cols, 5) - 0.55) * 8, 0, 1)
        g = g + 0.35 * light - 0.35 * dark
        img = base * (1.0 + g)[..., None]
        return Texture.from_image(img, a0, b0, texel)
    base = np.array(_WOODS[rng.integers(len(_WOODS))], np.float32)
    pw, pl = rng.uniform(0.12, 0.18), rng.uniform(0.9, 1.5)
    along_x = bool(rng.random() < 0.5)
    a = (np.arange(cols) * texel)[None, :]
    b = (np.arange(rows) * texel)[:, None]
    along, across = (a, b) if along_x else (b, a)
    row = np.floor(across / pw).astype(np.int64)
    n_rows = int(row.max()) + 1
    pos = along + rng.random(n_rows)[row] * pl
    idx = np.floor(pos / pl).astype(np.int64)
    n_idx = int(idx.max()) + 1
    tone = rng.normal(0.0, 0.12, (n_rows, n_idx)).astype(np.float32)[row, idx]
    mix = rng.random((n_rows, n_idx)).astype(np.float32)[row, idx]
    hue = rng.normal(0.0, 0.025, (n_rows, n_idx, 3)).astype(np.float32)[row, idx]
    # grain: streaks along the planks, two fields mixed per plank so it breaks at seams
    cr, cc = (3.0, 60.0) if along_x else (60.0, 3.0)
    grain = mix * _noise(rng, rows, cols, cr, cc) + (1 - mix) * _noise(rng, rows, cols, cr, cc)
    fine = _noise(rng, rows, cols, cr / 2, cc / 4)
    knots = np.clip(-_noise(rng, rows, cols, 8, 16) - 0.5, 0, None)  # sparse dark blotches
    d_side = np.minimum(across / pw - row, row + 1 - across / pw) * pw
    d_end = np.minimum(pos / pl - idx, idx + 1 - pos / pl) * pl
    w = max(0.0015, 0.6 * texel)
    seam = 1.0 - 0.6 * np.exp(-(np.minimum(d_side, d_end) / w) ** 2)
    shade = (1.0 + tone + 0.16 * grain + 0.07 * fine - 0.5 * knots) * seam
    img = base * (1.0 + hue) * shade[..., None].astype(np.float32)
    return Texture.from_image(img, a0, b0, texel)


def ceiling_texture(rng: np.random.Generator, bbox, texel: float = 0.02) -> Texture:
    """Light, nearly flat ceiling albedo over ``bbox`` (a = X, b = Z)."""
    xmin, zmin, xmax, zmax = (float(v) for v in bbox)
    rows, cols, texel = _grid(xmax - xmin + 0.2, zmax - zmin + 0.2, texel)
    img = np.float32(0.93) * (1.0 + 0.015 * _noise(rng, rows, cols, 40))[..., None]
    return Texture.from_image(np.repeat(img, 3, axis=2), xmin - 0.1, zmin - 0.1, texel)


def paint_colour(rng: np.random.Generator) -> np.ndarray:
    """(3,) BGR albedo of a room's paint."""
    return np.array(_PAINTS[rng.integers(len(_PAINTS))], np.float32)


def box_colour(rng: np.random.Generator) -> np.ndarray:
    """(3,) BGR albedo of a box (cabinet), distinct from the paints."""
    c = np.array(_BOXES[rng.integers(len(_BOXES))], np.float32)
    return np.clip(c * rng.uniform(0.9, 1.1, 3).astype(np.float32), 0, 1)


def wall_texture(rng: np.random.Generator, length: float, height: float, paint: np.ndarray,
                 baseboard_height: float = 0.08, texel: float = 0.005) -> Texture:
    """Wall albedo: a = metres along the edge, b = metres above the floor.

    Paint with mild noise, a darker baseboard band ``[0, baseboard_height]`` and framed
    posters with textured contents at mid-height."""
    rows, cols, texel = _grid(length, height, texel)
    tint = paint * rng.uniform(0.98, 1.02, 3).astype(np.float32)
    g = 0.025 * _noise(rng, rows, cols, 80) + 0.01 * _noise(rng, rows, cols, 4)
    img = tint * (1.0 + g)[..., None]
    bb = int(round(baseboard_height / texel))
    if bb > 0:
        img[:bb + 1] = tint * 0.5 * (1.0 + 0.5 * g[:bb + 1, :, None])
        img[bb:bb + 1] *= 0.8  # shadow line on top of the baseboard
    n_slots = int(length // 1.4)
    for k in range(n_slots):
        slot_w = length / n_slots
        if rng.random() > 0.85 or slot_w < 0.7:
            continue
        pw = rng.uniform(0.3, min(0.9, slot_w - 0.3))
        ph = rng.uniform(0.3, 0.7)
        cb = min(rng.uniform(1.25, 1.6), height - 0.15 - ph / 2)
        if cb - ph / 2 < baseboard_height + 0.3:
            continue
        ca = (k + 0.5) * slot_w + rng.uniform(-0.2, 0.2) * (slot_w - pw)
        c0, c1 = int(round((ca - pw / 2) / texel)), int(round((ca + pw / 2) / texel))
        r0, r1 = int(round((cb - ph / 2) / texel)), int(round((cb + ph / 2) / texel))
        c0, c1, r0, r1 = max(c0, 0), min(c1, cols), max(r0, 0), min(r1, rows)
        if c1 - c0 < 8 or r1 - r0 < 8:
            continue
        frame = max(2, int(round(rng.uniform(0.015, 0.035) / texel)))
        fcol = np.array(_BOXES[rng.integers(len(_BOXES))], np.float32) * 0.6
        img[r0:r1, c0:c1] = fcol
        img[r0 + frame:r1 - frame, c0 + frame:c1 - frame] = _poster(
            rng, r1 - r0 - 2 * frame, c1 - c0 - 2 * frame)[::-1]  # rows go up the wall
    return Texture.from_image(img, 0.0, 0.0, texel)


def _poster(rng: np.random.Generator, rows: int, cols: int) -> np.ndarray:
    """(rows, cols, 3) float32 BGR poster contents: colour fields plus random shapes."""
    lo = rng.random((int(rng.integers(2, 6)), int(rng.integers(2, 6)), 3), dtype=np.float32)
    img = cv2.resize(lo, (cols, rows), interpolation=cv2.INTER_CUBIC)
    img = np.clip(img * 255.0, 0, 255).astype(np.uint8)
    s = min(rows, cols)
    for _ in range(int(rng.integers(8, 20))):
        col = tuple(int(c) for c in rng.integers(0, 256, 3))
        p = (int(rng.integers(0, cols)), int(rng.integers(0, rows)))
        q = (int(rng.integers(0, cols)), int(rng.integers(0, rows)))
        kind = rng.integers(4)
        if kind == 0:
            cv2.circle(img, p, int(rng.integers(s // 20 + 1, s // 4 + 2)), col, -1, cv2.LINE_AA)
        elif kind == 1:
            cv2.rectangle(img, p, q, col, -1)
        elif kind == 2:
            cv2.line(img, p, q, col, int(rng.integers(2, max(3, s // 20))), cv2.LINE_AA)
        else:  # a block of "text": rows of short dark dashes
            h = max(3, s // 25)
            for r in range(int(rng.integers(2, 6))):
                x, y = p[0], p[1] + 2 * h * r
                while x < min(cols, p[0] + s // 2):
                    n = int(rng.integers(h, 4 * h))
                    cv2.rectangle(img, (x, y), (x + n, y + h), (30, 30, 30), -1)
                    x += n + h
    out = img.astype(np.float32) / 255.0
    return out * (1.0 + 0.04 * _noise(rng, rows, cols, 3))[..., None]
