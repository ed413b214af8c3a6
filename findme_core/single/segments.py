"""Straight segments of an image: detection, and one detection shared by every consumer.

Segments are (N, 4) float arrays ``[u1, v1, u2, v2]`` in pixels (pixel-centre origin).

A photo with gravity needs segments only below the horizon (``horizon_top_row``: floor lines
lie there). A photo without gravity needs them everywhere first (the vanishing directions
that give gravity, ``vanishing``), and then below the horizon that gravity implies: one
full-frame detection (``Segments``) serves both, so the photo is searched for lines once.
"""

from __future__ import annotations

import threading
from dataclasses import dataclass, field

import cv2
import numpy as np

from findme_core.errors import InputError
from findme_core.geometry.camera import Camera

SEGMENT_METHODS = ("lsd", "hough")
#: Long side of the image the hypotheses and the gravity estimate work on, pixels.
WORK_SIZE = 640
#: LSD's internal scale and the shortest segment kept at the working size (the hypotheses'
#: ``HypothesisParams.lsd_scale`` / ``min_segment_px``): what a shared detection uses.
LSD_SCALE = 0.5
MIN_SEGMENT_PX = 12.0


def _gray(image: np.ndarray) -> np.ndarray:
    if image.ndim == 3:
        return cv2.cvtColor(image, cv2.COLOR_BGR2GRAY)
    if image.ndim != 2:
        raise InputError(f"image must be HxW or HxWx3, got shape {image.shape}")
    return image


_LOCAL = threading.local()  # one LSD per thread and scale: detect() is not re-entrant


def _lsd(scale: float):
    cache = _LOCAL.__dict__.setdefault("lsd", {})
    if scale not in cache:
        cache[scale] = cv2.createLineSegmentDetector(cv2.LSD_REFINE_STD, scale)
    return cache[scale]


def horizon_top_row(camera: Camera, margin_px: float = 8.0) -> int:
    """First image row (even, >= 0) at or below which every floor line of ``camera`` lies:
    ``margin_px`` above the highest point of the horizon in the image; 0 when the horizon
    does not run across the image with the floor below it (the whole image is searched)."""
    a, b, c = camera.horizon_line()
    if b <= 1e-12 or abs(a) > 4 * b:  # floor not below the horizon, or horizon too steep
        return 0
    top = min(-(c + a * u) / b for u in (0.0, camera.width - 1.0)) - margin_px
    return int(np.clip(np.floor(top / 2) * 2, 0, max(camera.height - 2, 0)))


def _frame_edges(segs: np.ndarray, w: int, h: int, border_px: float) -> np.ndarray:
    """(N,) True for segments lying within ``border_px`` of one image border."""
    u, v = segs[:, [0, 2]], segs[:, [1, 3]]
    m = border_px
    return (u <= m).all(1) | (u >= w - 1 - m).all(1) | (v <= m).all(1) | (v >= h - 1 - m).all(1)


def _long_enough(segs: np.ndarray, min_length: float) -> np.ndarray:
    d = segs[:, 2:] - segs[:, :2]
    return np.hypot(d[:, 0], d[:, 1]) >= min_length


def detect_segments(image: np.ndarray, method: str = "lsd", min_length: float = 12.0,
                    lsd_scale: float = 0.8, border_px: float = 2.5,
                    top_row: int = 0) -> np.ndarray:
    """Detect straight segments.

    Args:
        image: (H, W) or (H, W, 3) uint8 (BGR).
        method: ``"lsd"`` (OpenCV LSD, sub-pixel) or ``"hough"`` (Canny + HoughLinesP, as the
            paper).
        min_length: drop segments shorter than this, pixels.
        lsd_scale: LSD's internal down-scaling (0.8 is LSD's default; smaller is faster).
        border_px: segments lying within this distance of one image border are the frame's
            own edge (dark borders), not scene lines, and are dropped.
        top_row: detect in rows >= ``top_row`` only (e.g. ``horizon_top_row``: the rows
            below the horizon, where floor lines are); an even row keeps LSD's sampling grid.
    Returns:
        (N, 4) float64 ``[u1, v1, u2, v2]`` in the pixels of the whole image.
    """
    gray = _gray(image)
    h, w = gray.shape
    top = int(np.clip(top_row, 0, max(h - 1, 0)))
    if method == "lsd":
        segs = _lsd(float(lsd_scale)).detect(gray[top:] if top else gray)[0]
        if segs is not None and top:
            segs = segs.reshape(-1, 4) + np.array([0, top, 0, top], np.float32)
    elif method == "hough":
        edges = cv2.Canny(gray[top:] if top else gray, 50, 150)
        segs = cv2.HoughLinesP(edges, 1, np.pi / 180, 40, minLineLength=int(min_length) + 8,
                               maxLineGap=4)
        if segs is not None:  # Canny marks the pixel before a step: shift to the step itself
            segs = segs.reshape(-1, 4).astype(float) + np.array([0.5, 0.5 + top, 0.5, 0.5 + top])
    else:
        raise InputError(f"unknown segment method {method!r}; choose one of {SEGMENT_METHODS}")
    if segs is None or len(segs) == 0:
        return np.zeros((0, 4))
    segs = np.asarray(segs, dtype=float).reshape(-1, 4)
    # edges of the image frame itself (dark borders left by rectification or registration)
    return segs[_long_enough(segs, min_length) & ~_frame_edges(segs, w, h, border_px)]


def clip_below(segs: np.ndarray, row: float) -> np.ndarray:
    """(N', 4) the parts of ``segs`` (N, 4) at or below image row ``row`` (a segment
    crossing the row is cut there; one wholly above it is dropped)."""
    segs = np.asarray(segs, float).reshape(-1, 4)
    p, q = segs[:, :2], segs[:, 2:]
    keep = (p[:, 1] >= row) | (q[:, 1] >= row)
    p, q = p[keep], q[keep]
    dv = q[:, 1] - p[:, 1]
    with np.errstate(divide="ignore", invalid="ignore"):
        t = np.where(np.abs(dv) > 1e-12, (row - p[:, 1]) / dv, 0.0)
    cut = p + t[:, None] * (q - p)
    p = np.where((p[:, 1] < row)[:, None], cut, p)
    q = np.where((q[:, 1] < row)[:, None], cut, q)
    return np.column_stack([p, q])


@dataclass(frozen=True)
class Segments:
    """One LSD detection of a whole image, shared by the gravity estimate and the
    hypotheses of the same photo (at the hypotheses' working size).

    Attributes:
        segs: (N, 4) segments in pixels of the ``width`` x ``height`` image, none shorter
            than ``min_length`` and none on the image's own border.
        width, height: size of the image they were detected in, pixels.
        lsd_scale: LSD's internal scale used.
        min_length: shortest segment kept, pixels.
        gray: (height, width) uint8 grey image they were detected in (for consumers that
            look at the image along lines: ``corners``), or None.
    """

    segs: np.ndarray
    width: int
    height: int
    lsd_scale: float
    min_length: float = MIN_SEGMENT_PX
    gray: np.ndarray | None = field(default=None, compare=False, repr=False)

    @classmethod
    def detect(cls, image: np.ndarray, lsd_scale: float = LSD_SCALE,
               min_length: float = MIN_SEGMENT_PX) -> "Segments":
        """LSD on the whole ``image`` ((H, W) or (H, W, 3) uint8)."""
        gray = _gray(image)
        h, w = gray.shape
        return cls(detect_segments(gray, "lsd", min_length, lsd_scale), w, h, float(lsd_scale),
                   float(min_length), gray)

    def fits(self, width: int, height: int, lsd_scale: float, min_length: float) -> bool:
        """Whether these are the segments a detection with these settings on an image of
        this size would give (else the consumer detects its own)."""
        return ((self.width, self.height) == (width, height) and self.lsd_scale == lsd_scale
                and self.min_length <= min_length)

    def below(self, top_row: int, min_length: float | None = None) -> np.ndarray:
        """(N', 4) the segments' parts in rows >= ``top_row`` (as a detection of those rows
        alone finds them: cut at the row), none shorter than ``min_length``."""
        segs = clip_below(self.segs, float(top_row)) if top_row > 0 else self.segs
        return segs[_long_enough(segs, self.min_length if min_length is None else min_length)]


def work_scale(height: int, width: int, work_size: int = WORK_SIZE) -> float:
    """The scale a ``height`` x ``width`` photo is worked at: work_size / its long side when
    that is under 0.95 (a photo barely larger is worked at full size), else 1."""
    s = min(1.0, work_size / max(height, width))
    return 1.0 if s >= 0.95 else s


def work_pixels(image: np.ndarray, work_size: int = WORK_SIZE) -> tuple[np.ndarray, float]:
    """(image, scale s) at the working size: the long side ``work_size`` pixels when the
    photo is larger (INTER_AREA; s = ``work_scale``), else the photo itself (s = 1)."""
    H, W = image.shape[:2]
    s = work_scale(H, W, work_size)
    if s == 1.0:
        return image, 1.0
    return cv2.resize(image, (round(W * s), round(H * s)), interpolation=cv2.INTER_AREA), s


def work_image(image: np.ndarray, camera: Camera,
               work_size: int = WORK_SIZE) -> tuple[np.ndarray, Camera, float]:
    """(image, camera, scale s) at the working size (``work_pixels``), the camera scaled to
    match."""
    small, s = work_pixels(image, work_size)
    if s == 1.0:
        return image, camera, 1.0
    cam = camera.scaled(s)
    return (small, Camera(cam.fx, cam.fy, cam.cx, cam.cy, small.shape[1], small.shape[0],
                          cam.gravity), s)


def photo_segments(image: np.ndarray, work_size: int = WORK_SIZE) -> Segments:
    """The whole-frame segments of a photo at the working size, as the hypotheses detect
    them (``LSD_SCALE``, ``MIN_SEGMENT_PX``): detected once for a photo without gravity,
    they give its gravity (``vanishing.estimate_gravity``) and then its hypotheses."""
    return Segments.detect(work_pixels(image, work_size)[0])
