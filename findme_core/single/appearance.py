"""Colour separability of a floor / not-floor split, for re-ranking hypotheses.

A correct ground-wall boundary splits the image into a floor region that is one surface
(homogeneous colour) and the rest. We measure how much a split explains the colours with
one Gaussian per region (a Chan-Vese / minimum-description-length criterion):

    gain = 1/2 log det C_all - (n_f / n) 1/2 log det C_floor - (n_w / n) 1/2 log det C_rest

in nats per pixel (>= 0 up to noise; 0 when the split explains nothing). Moments are
tabulated per sampled column as prefix sums over rows, so a candidate costs one gather per
sampled column.
"""

from __future__ import annotations

import cv2
import numpy as np

_EPS_VAR = 4.0   # colour variance floor (grey levels^2): keeps log det finite on flat regions


def to_lab(image: np.ndarray) -> np.ndarray:
    """(H, W, 3) uint8 BGR (or (H, W) grey) -> (H, W, 3) uint8 CIE Lab (OpenCV 8-bit scale).

    Kept in 8 bits: a quarter of the memory of float32, and the consumers sample it (remap,
    resize) or take moments in float64 themselves."""
    img = image if image.ndim == 3 else cv2.cvtColor(image, cv2.COLOR_GRAY2BGR)
    # OpenCV's own conversion, not Intel IPP's: the same bytes for every one of the 2^24
    # colours, and 1.55 ms against 1.81 for a 640x480 photo (the dev split's, one thread).
    # The IPP switch is per thread; this thread's is put back.
    ipp = cv2.ipp.useIPP()
    cv2.ipp.setUseIPP(False)
    try:
        return cv2.cvtColor(img, cv2.COLOR_BGR2LAB)
    finally:
        cv2.ipp.setUseIPP(ipp)


class RegionStats:
    """Prefix colour moments of an image on ``n_cols`` evenly spaced columns.

    Args:
        lab: (H, W, 3) Lab image (``to_lab``).
        n_cols: number of sampled columns.
        row_step: use every ``row_step``-th row (moments are scaled back to full rows).

    Attributes:
        prefix: (R + 1, 10, n_cols) moments (1, mean (3), upper second moments (6)) summed
            over the sampled rows above each row R; total: (10,) over the whole image.
    """

    def __init__(self, lab: np.ndarray, n_cols: int = 64, row_step: int = 2):
        H, W = lab.shape[:2]
        self.height, self.width, self.row_step = H, W, row_step
        self.cols = np.linspace(0, W - 1, n_cols).round().astype(int)
        x = np.moveaxis(lab[::row_step, self.cols], 2, 1).astype(np.float64)  # (R, 3, C)
        # prefix moments over rows, (R + 1, 10, C): 1, mean (3), upper second moments (6).
        # Row-major and built in place (one buffer, each row a contiguous block): numpy's
        # cumsum over a leading axis and a second 1 MB buffer each cost more than the rest
        P = np.empty((x.shape[0] + 1, 10, x.shape[2]))
        P[0] = 0.0
        P[1:, 0] = 1.0
        P[1:, 1:4] = x
        for k, (a, b) in enumerate(((0, 0), (0, 1), (0, 2), (1, 1), (1, 2), (2, 2))):
            np.multiply(x[:, a], x[:, b], out=P[1:, 4 + k])
        for i in range(1, len(P)):   # = np.cumsum(axis=0), the same sums in the same order
            np.add(P[i], P[i - 1], out=P[i])
        self.prefix = P
        # summed as a contiguous (C, 10) block: numpy sums a strided view in another order
        self.total = np.ascontiguousarray(P[-1].T).sum(0)   # (10,)

    def _logdet(self, m: np.ndarray) -> np.ndarray:
        """(K, 10) moments -> (K,) 1/2 log det of the covariance (regularised)."""
        n = np.maximum(m[:, 0], 1.0)
        mu = m[:, 1:4] / n[:, None]
        s = m[:, 4:10] / n[:, None]
        iu = ([0, 0, 0, 1, 1, 2], [0, 1, 2, 1, 2, 2])
        C = np.zeros((len(m), 3, 3))
        C[:, iu[0], iu[1]] = s
        C[:, iu[1], iu[0]] = s
        C -= mu[:, :, None] * mu[:, None, :]
        C += _EPS_VAR * np.eye(3)
        return 0.5 * np.linalg.slogdet(C)[1]

    def gain(self, rows: np.ndarray) -> np.ndarray:
        """(K, n_cols) boundary rows (floor = rows >= row) -> (K,) separability gain."""
        r = np.clip(np.ceil(np.asarray(rows, float) / self.row_step), 0,
                    self.prefix.shape[0] - 1).astype(int)
        P = self.prefix
        M, C = P.shape[1:]
        # (10, C, K): moment m of column c at row r[k, c], one gather; summed over the
        # columns one after another, c = 0, 1, ... (a sum over a leading axis, not pairwise)
        at = r.T * (M * C) + np.arange(C)[:, None]
        below = P[-1][:, :, None] - P.reshape(-1)[at[None] + (np.arange(M) * C)[:, None, None]]
        floor = below.sum(1).T   # (K, 10)
        rest = self.total[None, :] - floor
        n = self.total[0]
        g_all = self._logdet(self.total[None, :])[0]
        nf, nr = floor[:, 0], rest[:, 0]
        return g_all - (nf / n) * self._logdet(floor) - (nr / n) * self._logdet(rest)


class FloorLikelihood:
    """Per-pixel floor / not-floor log-likelihood ratio from two colour Gaussians fitted to
    a first split of the image, tabulated as column sums below each row.

    ``below(u, v)`` = sum over rows >= v of the clipped ratio in column u, divided by the
    image height: the reward (in [-clip, clip]) for calling everything below row v floor.
    Computed on a quarter-resolution Lab image (``lab`` from ``to_lab``).
    """

    def __init__(self, lab: np.ndarray, floor_rows: np.ndarray, clip: float = 3.0,
                 margin_px: float = 3.0, scale: int = 4):
        H, W = lab.shape[:2]
        lab = cv2.resize(lab, (W // scale, H // scale),
                         interpolation=cv2.INTER_AREA).astype(np.float32)
        h, w = lab.shape[:2]
        self.scale, self.height, self.width = scale, H, W
        b = np.interp((np.arange(w) + 0.5) * scale - 0.5, np.arange(W), floor_rows)
        rr = (np.arange(h)[:, None] + 0.5) * scale - 0.5
        floor = rr >= b[None, :] + margin_px
        rest = rr < b[None, :] - margin_px
        x = lab.reshape(-1, 3)
        self.valid = bool(floor.sum() >= 50 and rest.sum() >= 50)
        if not self.valid:
            self.table = np.zeros((h + 1, w))
            return
        llr = _gauss_loglik(x, x[floor.ravel()]) - _gauss_loglik(x, x[rest.ravel()])
        llr = np.clip(llr, -clip, clip).reshape(h, w)
        T = np.zeros((h + 1, w))
        T[:h] = np.cumsum(llr[::-1], axis=0)[::-1]
        self.table = T / h

    def below(self, rows: np.ndarray) -> np.ndarray:
        """(K, W) boundary rows at every full-resolution column -> (K, W) region reward."""
        h, w = self.table.shape[0] - 1, self.table.shape[1]
        r = np.clip(np.ceil((np.asarray(rows) + 0.5) / self.scale - 0.5), 0, h).astype(int)
        c = np.clip((np.arange(self.width) // self.scale), 0, w - 1)
        return self.table[r, c[None, :]]


def _gauss_loglik(x: np.ndarray, sample: np.ndarray) -> np.ndarray:
    """Log density (up to a shared constant) of (M, 3) colours under a Gaussian of a sample."""
    mu = sample.mean(0)
    C = np.cov(sample.T) + _EPS_VAR * np.eye(3)
    Ci = np.linalg.inv(C)
    d = x - mu
    q = (d @ Ci) * d     # its rows summed (q0 + q1) + q2, as .sum(1) does, without a reduction
    return -0.5 * (q[:, 0] + q[:, 1] + q[:, 2]) - 0.5 * np.linalg.slogdet(C)[1]   # over 3
