"""A layout's scan looked up by azimuth: the nearest boundary sample in a direction
(``Layout.scan``; used by the registration of two layouts, ``register``, and by the
photometric agreement, ``motion_photometric``).

Azimuth: atan2(x, z) in the photo's level frame, radians, > 0 to the right. Pure numpy.
"""

from __future__ import annotations

import numpy as np


class Scan:
    """A layout's scan samples looked up by azimuth (radians, atan2(x, z) in the level
    frame): the nearest sample (halfway between two samples, up to rounding, either), in a few
    array passes and no search.

    The middles between consecutive samples split the azimuth axis. Bins of width 2^-p, at
    most half the smallest gap between middles (so a bin holds at most one middle), each
    know how many middles lie at or below their start; floor(az 2^p) is exact, so an
    azimuth's bin is, and one comparison with the next middle completes the count. Without
    such bins (fewer than 3 samples, or middles closer than 1e-6 rad) a binary search."""

    MAX_BINS = 1 << 16

    def __init__(self, layout):
        a = layout.azimuth   # (K,) ascending, K >= 2
        self.azimuth, self.spacing = a, layout.spacing
        self.middles = m = 0.5 * (a[:-1] + a[1:])
        self.bins = None
        gap = float(np.diff(m).min()) if len(m) > 1 else 0.0
        if gap > 1e-6:
            scale = 2.0 ** (int(np.ceil(-np.log2(gap))) + 1)
            first = np.floor(m[0] * scale) - 1.0            # starts below the first middle
            n = int(np.floor(m[-1] * scale) - first) + 2    # the last starts above the last
            if n <= self.MAX_BINS:
                below = np.searchsorted(m, (first + np.arange(n)) / scale, side="right")
                self.bins = (scale, first, n, below, np.append(m, np.inf))

    def nearest(self, az: np.ndarray):
        """(...) index of the nearest sample to each azimuth of ``az`` (...), and (...)
        whether it is near (within 1.5 sample spacings; NaN: never)."""
        az = np.asarray(az, float)
        if self.bins is None:
            j = np.searchsorted(self.middles, az, side="right")
        else:
            scale, first, n, below, after = self.bins
            k = np.floor(az * scale, out=np.empty(az.shape))
            k -= first
            np.fmax(k, 0.0, out=k)          # (NaN -> bin 0: not near)
            np.fmin(k, n - 1.0, out=k)
            j = below[k.astype(np.intp)]
            j += az >= after[j]
        return j, np.abs(az - self.azimuth[j]) < 1.5 * self.spacing
