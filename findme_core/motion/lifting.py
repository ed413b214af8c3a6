"""Matched pixels lifted to 3D (paper step 5, "matched points are lifted to 3D under each
photo's chosen boundary"): ``lift`` asks a photo's ``Scene`` for the 3D of matched pixels
(floor: eq. 2, wall: eqs. 3-4) and returns them in that photo's LEVEL frame (y down along
gravity, floor at y = h, metres) with their 1-sigma radius.

Pure numpy; no I/O, clocks or environment.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


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
    """3D of ``pixels`` (N, 2) under ``scene`` (a ``findme_core.single.scene.Scene``), in the
    photo's level frame; only the rows in ``select`` (bool mask or indices) are computed,
    the others have no 3D (vectorised: ``Scene.locate_level``)."""
    px = np.asarray(pixels, float).reshape(-1, 2)
    out = Lifted.empty(len(px))
    rows = np.arange(len(px)) if select is None else np.arange(len(px))[select]
    if scene is None or len(rows) == 0:
        return out
    P, surface, sigma, _, reason = scene.locate_level(px[rows])
    ok = (reason == 0) & np.isfinite(sigma)
    out.points[rows[ok]] = P[ok]
    out.sigma[rows[ok]] = sigma[ok]
    out.floor[rows[ok]] = surface[ok] == 1
    return out
