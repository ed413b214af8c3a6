"""Point features of one photo and putative matches between two photos (paper step 5).

The paper used SURF, which pip OpenCV does not ship. The detector was chosen by measurement
on the findme-eval dev pairs (end to end with ``methods``, and ``bench/bench_motion.py``):
ORB with a low FAST threshold (5) and 3000 keypoints spread over an 8 x 6 grid. Against
SIFT (3000) it keeps ~5x more correct matches on the nearly textureless TUM views (median
54 vs 11 within 1 deg of the true epipolar plane) and the motion answered 99 % of the TUM
pairs vs 77 %, for ~12 ms of features per pair vs ~100-240 ms (one core); without the grid
the strongest corners crowd onto textured walls and trees and the floor, which fixes the
scale, gets few (KITTI median translation error 0.8 m vs < 0.1 m); 1500 or 2000 keypoints
lose pairs in the white ZInD rooms. SIFT stays available.

Frames and units: keypoints are pixels (u, v) of the image they come from (origin at the
centre of the top-left pixel, OpenCV's keypoint convention). Descriptors are uint8 (ORB,
256-bit binary, compared by Hamming distance) or float32 (SIFT, 128-D, L2).

Matching: k = 2 nearest neighbours both ways, Lowe's ratio test (the best match must be
clearly better than the second best) and a mutual (cross) check. Geometric verification
is done where the geometry is known: by the gravity-aware RANSAC of ``methods``. Lifting
the matched pixels to 3D is ``lifting``.

Pure: numpy and OpenCV in, arrays out; no I/O, clocks or environment.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from findme_core.errors import InputError

DETECTORS = ("orb", "sift")
MATCHERS = ("auto", "brute", "lsh")
_LSH = dict(algorithm=6, table_number=6, key_size=12, multi_probe_level=1)   # FLANN LSH


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
        grid: (columns, rows) of cells over which the keypoints are spread: each cell keeps
            its strongest ``n_features / cells``, the rest go to the strongest anywhere (so
            the faint floor gets keypoints next to a textured wall or tree); None: off.
        oversample: candidates detected per kept keypoint when ``grid`` is on.
        matcher: "brute" (exact nearest neighbours), "lsh" (FLANN locality-sensitive
            hashing of binary descriptors: approximate, 2-5x faster for 3000 ORB keypoints
            with this OpenCV build, whose Hamming distance is not vectorised; its hash
            tables are seeded, so results repeat) or "auto" (lsh for ORB, brute for SIFT).
    """

    detector: str = "orb"
    n_features: int = 3000
    fast_threshold: int = 5
    sift_contrast: float = 0.02
    ratio: float = 0.9
    mutual: bool = True
    grid: tuple | None = (8, 6)
    oversample: float = 3.0
    matcher: str = "auto"

    def __post_init__(self) -> None:
        if self.detector not in DETECTORS:
            raise InputError(f"unknown detector {self.detector!r}; choose one of "
                             f"{', '.join(DETECTORS)}")
        if self.n_features < 8:
            raise InputError(f"n_features must be at least 8, got {self.n_features}")
        if not 0.0 < self.ratio <= 1.0:
            raise InputError(f"ratio must be in (0, 1], got {self.ratio}")
        if self.matcher not in MATCHERS:
            raise InputError(f"unknown matcher {self.matcher!r}; choose one of "
                             f"{', '.join(MATCHERS)}")
        if self.matcher == "lsh" and self.detector != "orb":
            raise InputError(f"the lsh matcher needs binary descriptors (orb), not {self.detector}")


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
    n = int(p.n_features * (p.oversample if p.grid else 1.0))
    if p.detector == "orb":
        return cv2.ORB_create(nfeatures=n, fastThreshold=p.fast_threshold)
    return cv2.SIFT_create(nfeatures=n, contrastThreshold=p.sift_contrast)


def _pixels(kps) -> np.ndarray:
    """(N, 2) float64 positions (u, v) of OpenCV keypoints ((0, 2) for none)."""
    return np.asarray(cv2.KeyPoint_convert(kps), float).reshape(-1, 2)


def _spread(kps, width: int, height: int, n: int, grid) -> np.ndarray:
    """(K,) ascending indices into ``kps`` of at most ``n`` keypoints: the strongest
    n / cells of each grid cell, then the strongest of the rest (all of them without a
    ``grid`` or when there are no more than ``n``)."""
    if not grid or len(kps) <= n:
        return np.arange(len(kps))
    resp = np.array([k.response for k in kps])
    xy = _pixels(kps)
    gx, gy = grid
    cell = (np.minimum((xy[:, 0] * gx / width).astype(int), gx - 1) * gy
            + np.minimum((xy[:, 1] * gy / height).astype(int), gy - 1))
    order = np.lexsort((-resp, cell))            # by cell, strongest first
    first = np.searchsorted(cell[order], np.arange(gx * gy))
    rank = np.empty(len(kps), int)
    rank[order] = np.arange(len(kps)) - first[cell[order]]
    keep = rank < n // (gx * gy)
    rest = np.flatnonzero(~keep)
    # strongest first, equal responses in index order (an unstable sort orders ties by the
    # CPU's sort kernel: AVX-512 and AVX2 machines kept different keypoints)
    rest = rest[np.argsort(-resp[rest], kind="stable")][:max(0, n - int(keep.sum()))]
    keep[rest] = True
    return np.flatnonzero(keep)


def detect(image: np.ndarray, params: FeatureParams = FeatureParams()) -> Features:
    """Keypoints and descriptors of one photo ((H, W, 3) BGR or (H, W) grey uint8)."""
    grey = _grey(image)
    H, W = grey.shape
    det = _detector(params)
    if params.grid and params.detector == "sift":
        # SIFT describes at the octaves of the keypoints it is given: describe the kept ones
        found = det.detect(grey, None)
        kps = [found[i] for i in _spread(found, W, H, params.n_features, params.grid)]
        kps, desc = det.compute(grey, kps) if kps else ((), None)
        rows = np.arange(len(kps))
    else:
        # ORB describes each keypoint on its own: the kept ones' rows, one pyramid built
        kps, desc = det.detectAndCompute(grey, None)
        rows = _spread(kps, W, H, params.n_features, params.grid)
    if desc is None or not kps:
        dim, dt = (32, np.uint8) if params.detector == "orb" else (128, np.float32)
        return Features(np.zeros((0, 2)), np.zeros((0, dim), dt), np.zeros(0), params.detector,
                        W, H)
    sizes = np.array([kps[i].size for i in rows.tolist()], dtype=float)
    return Features(_pixels(kps)[rows], desc[rows], sizes, params.detector, W, H)


def _nearest(query: np.ndarray, train: np.ndarray, k: int, lsh: bool, binary: bool):
    """(Nq, k) int indices into ``train`` (>= k rows) of the k nearest neighbours of each
    row of ``query``, and their (Nq, k) float distances, nearest first (-1 / inf where LSH
    found fewer). LSH: FLANN's index over ``train`` as ``cv2.FlannBasedMatcher`` builds it,
    hash tables from OpenCV's RNG (the caller seeds it); else exact, finding all k."""
    if lsh:
        idx, dist = cv2.flann_Index(train, _LSH).knnSearch(query, k, params=dict(checks=32))
        idx = idx.astype(int).reshape(len(query), k)
        return idx, np.where(idx >= 0, dist.reshape(len(query), k), np.inf)
    found = cv2.BFMatcher(cv2.NORM_HAMMING if binary else cv2.NORM_L2).knnMatch(query, train, k)
    ms = [m for pair in found for m in pair]
    return (np.array([m.trainIdx for m in ms], int).reshape(-1, k),
            np.array([m.distance for m in ms], float).reshape(-1, k))


def match(fa: Features, fb: Features, params: FeatureParams = FeatureParams()) -> Matches:
    """Putative matches A -> B: 2 nearest neighbours, Lowe's ratio test, then (optionally)
    the mutual check (B's keypoint's best match in A must be the same keypoint), run only
    for the B keypoints that survived the ratio test.

    Returns empty ``Matches`` when either photo has fewer than 2 keypoints; callers decide
    whether that is an error (``methods`` raises ``MotionError`` naming the counts).
    """
    if fa.detector != fb.detector:
        raise InputError(f"cannot match {fa.detector} features with {fb.detector} features")
    empty = Matches(np.zeros((0, 2)), np.zeros((0, 2)), np.zeros(0, int), np.zeros(0, int),
                    np.zeros(0), len(fa), len(fb))
    if len(fa) < 2 or len(fb) < 2:
        return empty
    binary = fa.detector == "orb"
    if params.matcher == "lsh" and not binary:
        raise InputError(f"the lsh matcher needs binary descriptors (orb), not {fa.detector}")
    lsh = params.matcher == "lsh" or (params.matcher == "auto" and binary)
    if lsh:
        cv2.setRNGSeed(0)   # LSH hash tables come from OpenCV's (thread-local) RNG: repeatable
    idx, dist = _nearest(fa.descriptors, fb.descriptors, 2, lsh, binary)
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = np.where(dist[:, 1] > 0, dist[:, 0] / dist[:, 1], 1.0)
    ia = np.flatnonzero((idx[:, 0] >= 0) & (ratio < params.ratio))
    ib = idx[ia, 0]
    if params.mutual and len(ia):
        cand = np.unique(ib)
        back = np.full(len(fb), -1)
        back[cand] = _nearest(fb.descriptors[cand], fa.descriptors, 1, lsh, binary)[0][:, 0]
        keep = back[ib] == ia   # (-1: LSH found no match back)
        ia, ib = ia[keep], ib[keep]
    if len(ia) == 0:
        return empty
    return Matches(fa.pixels[ia], fb.pixels[ib], ia, ib, ratio[ia], len(fa), len(fb))


def distinct(matches: Matches, radius_px: float) -> tuple[np.ndarray, np.ndarray]:
    """The matches that are not near-duplicates of a more distinctive one.

    ORB finds one corner at several pyramid levels, and each copy is matched: the copies
    are one observation, yet each would count as an inlier of whichever motion it fits
    (a door frame's corner, five times over, outvoting the room). Two matches are copies
    when their distances in A and in B add up to less than ``2 * radius_px`` pixels; of a
    group the one with the lowest ratio is kept (greedy, most distinctive first).

    Returns:
        (keep (K,) indices of the kept matches, ascending; of (M,) the position in ``keep``
        of each match's representative).
    """
    n = len(matches)
    if n == 0:
        return np.zeros(0, int), np.zeros(0, int)
    if n <= 256:   # small: the whole (n, n) matrix is cheaper than the grid
        def dist(u):   # (n, n) pixel distances (the norm over the pair axis, written out)
            dx, dy = u[:, None, 0] - u[None, :, 0], u[:, None, 1] - u[None, :, 1]
            return np.sqrt(dx * dx + dy * dy)
        ii, jj = np.nonzero(dist(matches.ua) + dist(matches.ub) < 2.0 * radius_px)
    else:          # O(n) candidates instead of n^2 (a textured pair has 1,000-3,000 matches)
        ii, jj = _copies(matches.ua, matches.ub, 2.0 * radius_px)
    # each match's copies (itself included) as lists: the greedy pass is then plain Python
    near = np.split(jj, np.searchsorted(ii, np.arange(1, n))) if n > 1 else [jj]
    rep = [-1] * n
    for i in np.argsort(matches.ratio, kind="stable").tolist():
        if rep[i] < 0:
            for j in near[i].tolist():
                if rep[j] < 0:
                    rep[j] = i
    rep = np.array(rep)
    keep = np.unique(rep)
    return keep, np.searchsorted(keep, rep)


def _copies(ua: np.ndarray, ub: np.ndarray, limit: float) -> tuple[np.ndarray, np.ndarray]:
    """(i, j) of every ordered pair of matches (i == j included) with |ua_i - ua_j| +
    |ub_i - ub_j| < ``limit``, sorted by i then j: what ``np.nonzero`` of the (n, n)
    distance matrix gives, without building it. Candidates are the pairs whose A pixels
    lie in the same or neighbouring cells of a grid of ``limit`` px (each term is below the
    sum); each candidate's sum is computed as the matrix would (same operations, same
    order: bit-identical)."""
    n = len(ua)
    cell = np.floor(ua / limit).astype(np.int64)            # (n, 2)
    order = np.lexsort((cell[:, 1], cell[:, 0]))
    cx, cy = cell[order, 0], cell[order, 1]
    keys = cx * (1 << 32) + cy
    ii, jj = [], []
    for dx in (-1, 0, 1):
        for dy in (-1, 0, 1):
            want = (cx + dx) * (1 << 32) + (cy + dy)        # each match's neighbour cell
            lo = np.searchsorted(keys, want, "left")
            hi = np.searchsorted(keys, want, "right")
            cnt = hi - lo
            if not cnt.any():
                continue
            src = np.repeat(order, cnt)                     # i (original index)
            start = np.repeat(lo - np.cumsum(cnt) + cnt, cnt)
            dst = order[np.arange(cnt.sum()) + start]       # j in that cell
            ii.append(src)
            jj.append(dst)
    i = np.concatenate(ii)
    j = np.concatenate(jj)

    def dist(u):   # the pixel distance of each pair (the norm written out, as before)
        dx, dy = u[i, 0] - u[j, 0], u[i, 1] - u[j, 1]
        return np.sqrt(dx * dx + dy * dy)
    keep = dist(ua) + dist(ub) < limit
    i, j = i[keep], j[keep]
    o = np.lexsort((j, i))
    return i[o], j[o]
