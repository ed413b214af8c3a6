"""Point features of one photo and putative matches between two photos (paper step 5).

The paper used SURF, which pip OpenCV does not ship. The detector is chosen by measurement
on the findme-eval pairs (``bench/bench_motion.py`` and the report in the motion PR):
ORB with a low FAST threshold finds more correct matches than SIFT on the nearly
textureless TUM and ZInD views at a fraction of the time; SIFT stays available.

Frames and units: keypoints are pixels (u, v) of the image they come from (origin at the
centre of the top-left pixel, OpenCV's keypoint convention). Descriptors are uint8 (ORB,
256-bit binary, compared by Hamming distance) or float32 (SIFT, 128-D, L2).

Matching: k = 2 nearest neighbours both ways, Lowe's ratio test (the best match must be
clearly better than the second best) and a mutual (cross) check. Geometric verification
is done where the geometry is known: by the gravity-aware RANSAC of ``motion``.

Lifting (paper step 5, "matched points are lifted to 3D under each photo's chosen
boundary"): ``lift`` asks a photo's ``Scene`` for the 3D of matched pixels (floor: eq. 2,
wall: eqs. 3-4) and returns them in that photo's LEVEL frame with their 1-sigma radius.

Pure: numpy and OpenCV in, arrays out; no I/O, clocks or environment.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from .errors import InputError

DETECTORS = ("orb", "sift")


@dataclass(frozen=True)
class FeatureParams:
    """Detector and matcher settings (pixels of a ~640 px image).

    Attributes:
        detector: "orb" or "sift".
        n_features: at most this many keypoints per image.
        fast_threshold: ORB's FAST corner threshold (grey levels); low finds corners on
            faint texture (carpet, white walls).
        sift_contrast: SIFT's contrast threshold.
        ratio: Lowe's ratio test: best distance < ratio * second best.
        mutual: keep only matches that are each other's best match both ways.
    """

    detector: str = "orb"
    n_features: int = 3000
    fast_threshold: int = 5
    sift_contrast: float = 0.02
    ratio: float = 0.8
    mutual: bool = True

    def __post_init__(self) -> None:
        if self.detector not in DETECTORS:
            raise InputError(f"unknown detector {self.detector!r}; choose one of "
                             f"{', '.join(DETECTORS)}")
        if self.n_features < 8:
            raise InputError(f"n_features must be at least 8, got {self.n_features}")
        if not 0.0 < self.ratio <= 1.0:
            raise InputError(f"ratio must be in (0, 1], got {self.ratio}")


@dataclass(frozen=True)
class Features:
    """Keypoints of one photo.

    Attributes:
        pixels: (N, 2) float64 keypoint positions (u, v).
        descriptors: (N, D) uint8 (ORB) or float32 (SIFT).
        sizes: (N,) keypoint diameters in pixels (the detector's scale).
        detector: name of the detector that made them.
        width, height: size of the image.
    """

    pixels: np.ndarray
    descriptors: np.ndarray
    sizes: np.ndarray
    detector: str
    width: int
    height: int

    def __len__(self) -> int:
        return len(self.pixels)


@dataclass(frozen=True)
class Matches:
    """Putative correspondences between photo A and photo B.

    Attributes:
        ua, ub: (M, 2) pixels in A and in B of each match.
        ia, ib: (M,) keypoint indices into A's and B's ``Features``.
        ratio: (M,) best / second-best descriptor distance (lower = more distinctive).
        n_a, n_b: keypoints found in A and in B.
    """

    ua: np.ndarray
    ub: np.ndarray
    ia: np.ndarray
    ib: np.ndarray
    ratio: np.ndarray
    n_a: int
    n_b: int

    def __len__(self) -> int:
        return len(self.ua)

    def subset(self, keep) -> "Matches":
        """The matches selected by a boolean mask or index array."""
        return Matches(self.ua[keep], self.ub[keep], self.ia[keep], self.ib[keep],
                       self.ratio[keep], self.n_a, self.n_b)


def _grey(image: np.ndarray) -> np.ndarray:
    if not isinstance(image, np.ndarray) or image.dtype != np.uint8 or image.ndim not in (2, 3):
        raise InputError("image must be a uint8 HxW or HxWx3 array, got "
                         f"{getattr(image, 'dtype', type(image))} {getattr(image, 'shape', '')}")
    if image.ndim == 3:
        if image.shape[2] != 3:
            raise InputError(f"a colour image must have 3 channels, got {image.shape[2]}")
        return cv2.cvtColor(image, cv2.COLOR_BGR2GRAY)
    return image


def _detector(p: FeatureParams):
    if p.detector == "orb":
        return cv2.ORB_create(nfeatures=p.n_features, fastThreshold=p.fast_threshold)
    return cv2.SIFT_create(nfeatures=p.n_features, contrastThreshold=p.sift_contrast)


def detect(image: np.ndarray, params: FeatureParams = FeatureParams()) -> Features:
    """Keypoints and descriptors of one photo ((H, W, 3) BGR or (H, W) grey uint8)."""
    grey = _grey(image)
    kps, desc = _detector(params).detectAndCompute(grey, None)
    H, W = grey.shape
    if desc is None or not kps:
        dim, dt = (32, np.uint8) if params.detector == "orb" else (128, np.float32)
        return Features(np.zeros((0, 2)), np.zeros((0, dim), dt), np.zeros(0), params.detector,
                        W, H)
    pix = np.array([k.pt for k in kps], dtype=float).reshape(-1, 2)
    sizes = np.array([k.size for k in kps], dtype=float)
    return Features(pix, desc, sizes, params.detector, W, H)


def _knn(d1: np.ndarray, d2: np.ndarray, norm: int) -> tuple[np.ndarray, np.ndarray]:
    """(N1, 2) indices and distances of the two nearest neighbours in d2 of each row of d1
    (second column inf / -1 when d2 has one row)."""
    idx = np.full((len(d1), 2), -1, int)
    dist = np.full((len(d1), 2), np.inf)
    for i, pair in enumerate(cv2.BFMatcher(norm).knnMatch(d1, d2, k=2)):
        for j, m in enumerate(pair[:2]):
            idx[i, j], dist[i, j] = m.trainIdx, m.distance
    return idx, dist


def match(fa: Features, fb: Features, params: FeatureParams = FeatureParams()) -> Matches:
    """Putative matches A -> B: ratio test, then (optionally) the mutual check.

    Returns empty ``Matches`` when either photo has fewer than 2 keypoints; callers decide
    whether that is an error (``motion`` raises ``MotionError`` naming the counts).
    """
    if fa.detector != fb.detector:
        raise InputError(f"cannot match {fa.detector} features with {fb.detector} features")
    empty = Matches(np.zeros((0, 2)), np.zeros((0, 2)), np.zeros(0, int), np.zeros(0, int),
                    np.zeros(0), len(fa), len(fb))
    if len(fa) < 2 or len(fb) < 2:
        return empty
    norm = cv2.NORM_HAMMING if fa.detector == "orb" else cv2.NORM_L2
    idx, dist = _knn(fa.descriptors, fb.descriptors, norm)
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = np.where(dist[:, 1] > 0, dist[:, 0] / dist[:, 1], 1.0)
    keep = (idx[:, 0] >= 0) & (ratio < params.ratio)
    if params.mutual and keep.any():
        back, _ = _knn(fb.descriptors, fa.descriptors, norm)
        ia_all = np.arange(len(fa))
        keep &= back[np.maximum(idx[:, 0], 0), 0] == ia_all
    ia = np.flatnonzero(keep)
    if len(ia) == 0:
        return empty
    ib = idx[ia, 0]
    return Matches(fa.pixels[ia], fb.pixels[ib], ia, ib, ratio[ia], len(fa), len(fb))


@dataclass(frozen=True)
class Lifted:
    """3D of matched pixels of one photo under its chosen hypothesis.

    Attributes:
        points: (N, 3) metres in the photo's LEVEL frame (y down, floor at y = h);
            NaN rows where the pixel has no 3D (above the horizon with no wall known, ...).
        sigma: (N,) 1-sigma radius in metres (``Scene.locate``); inf where no 3D.
        floor: (N,) True where the point is on the floor (eq. 2), False on a wall / none.
    """

    points: np.ndarray
    sigma: np.ndarray
    floor: np.ndarray

    @property
    def valid(self) -> np.ndarray:
        """(N,) bool: the pixel has a 3D point."""
        return np.isfinite(self.points[:, 0])

    @classmethod
    def empty(cls, n: int) -> "Lifted":
        """``n`` pixels without 3D (a photo without a usable hypothesis)."""
        return cls(np.full((n, 3), np.nan), np.full(n, np.inf), np.zeros(n, bool))


def lift(scene, pixels, select=None) -> Lifted:
    """3D of ``pixels`` (N, 2) under ``scene`` (a ``findme_core.scene.Scene``), in the
    photo's level frame; only the rows in ``select`` (bool mask or indices) are computed
    (``Scene.locate`` costs ~0.25 ms a point), the others have no 3D."""
    px = np.asarray(pixels, float).reshape(-1, 2)
    out = Lifted.empty(len(px))
    rows = np.arange(len(px)) if select is None else np.arange(len(px))[select]
    if scene is None or len(rows) == 0:
        return out
    R = scene.camera.R_level_from_cam
    for i, loc in zip(rows, scene.locate(px[rows])):
        if loc.xyz is not None and np.isfinite(loc.sigma_m):
            out.points[i] = R @ loc.xyz
            out.sigma[i] = loc.sigma_m
            out.floor[i] = loc.surface == "floor"
    return out
