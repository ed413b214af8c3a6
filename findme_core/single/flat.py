"""A boundary that separates nothing: where the photo is the same colour just above and just
below it, no floor meets a wall there.

A floor-wall boundary parts two surfaces of different material and light, so the colour
steps across it even where no sharp edge runs along it. A level photo of a blank wall with
posters on it shows no floor, yet its best boundary may follow a poster's lower edge and run
on across the blank wall just below the horizon, where above and below are one coat of paint
(a step of about 1 unit of OpenCV's 8-bit Lab): as a floor line it puts the wall metres away
and the wall below it on the floor, 3.3 m off at +-0.10 m (README, "No floor in view").

``flat_share`` measures, over the boundary's WALL columns inside the photo, the share where
the mean colour of a band of ``BAND`` rows just above (``GAP`` rows clear of it) and of the
same band just below differ by less than ``FLAT_STEP``, strip by strip of ``COLUMN_STEP``
columns. ``separates_nothing``: half of them or more (``FLAT_SHARE``) over at least
``MIN_COLUMNS`` strips. Constants set by what they mean (the bands: a few pixels clear of a
blurred edge, a stripe of texture; the step: a few units, over the 0.7-1.8 that one rendered
coat of paint across a poster's boundary steps by after JPEG; "most of its length": a half),
then checked (2026-12-02):
of 18 rendered level photos of walls with posters (6 walls x 0.8-1.3 m) 17 show no floor now
(11 before); the dev split's top-1 boundaries have a flat share of median 0, 99th percentile
0.36-0.38 (the dataset's gravity, withheld), highest 0.48: a window on a blank wall with no
floor in view, not caught (README).

Sums of 8-bit integers, compared in integers: the same answer on every machine.

Frames and units: image pixels (u right, v down) of the working-size photo ``lab`` (H, W, 3)
uint8, OpenCV's 8-bit CIE Lab; polylines (M, 2) with u non-decreasing, kinds (M - 1,)
``SegKind``. Pure numpy; no I/O.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from findme_core.single.search import SegKind

#: rows between the boundary and each band (pixels at the 640 px working size)
GAP = 4
#: rows of each band (pixels at the working size)
BAND = 20
#: columns of each band: the photo is cut into strips this wide, each one measured
COLUMN_STEP = 4
#: a colour step under this (Euclidean, OpenCV 8-bit Lab units) is no step
FLAT_STEP = 3
#: a boundary separates nothing when at least this share of its measured strips is flat
FLAT_SHARE = 0.5
#: ... measured over at least this many strips (else it is not judged: 0)
MIN_COLUMNS = 16


def flat_share(lab: np.ndarray, poly, kinds) -> float:
    """Share in [0, 1] of the boundary's measured WALL strips across which the colour does
    not step (0 when fewer than ``MIN_COLUMNS`` are measured). ``lab``: (H, W, 3) uint8, the
    photo cut into strips of ``COLUMN_STEP`` columns; ``poly`` (M, 2), ``kinds`` (M - 1,) as
    a ``Hypothesis``'s; a strip's boundary row is the polyline's at its centre, rounded."""
    H, W = lab.shape[:2]
    poly = np.asarray(poly, float)
    kinds = np.asarray(kinds)
    x0 = COLUMN_STEP * np.arange(W // COLUMN_STEP)                 # each strip's first column
    us = x0 + (COLUMN_STEP - 1) / 2.0                              # and its centre
    seg = np.clip(np.searchsorted(poly[:, 0], us, side="right") - 1, 0, len(kinds) - 1)
    vs = np.interp(us, poly[:, 0], poly[:, 1])
    ok = (kinds[seg] == SegKind.WALL) & (vs >= GAP + BAND) & (vs < H - GAP - BAND)
    x0, v = x0[ok], np.rint(vs[ok]).astype(int)
    if len(x0) < MIN_COLUMNS:
        return 0.0
    cols = (x0[:, None] + np.arange(COLUMN_STEP))[:, None, :]     # (C, 1, 4)
    band = np.arange(BAND)[None, :, None]                          # (1, 20, 1)
    above = lab[(v - GAP - BAND)[:, None, None] + band, cols].sum((1, 2), dtype=np.int64)
    below = lab[(v + GAP)[:, None, None] + band, cols].sum((1, 2), dtype=np.int64)
    n = BAND * COLUMN_STEP                      # pixels in each band: equal, so the means
    d2 = ((above - below) ** 2).sum(1)          # differ by less than FLAT_STEP exactly when
    flat = d2 < (FLAT_STEP * n) ** 2            # the sums differ by less than FLAT_STEP * n
    return float(np.count_nonzero(flat)) / len(x0)


def separates_nothing(share: float) -> bool:
    """Whether a boundary with ``flat_share`` ``share`` separates nothing along most of it."""
    return share >= FLAT_SHARE


def no_floor_first(hyps: list, lab: np.ndarray, max_n: int) -> list:
    """``hyps`` (``hypotheses.Hypothesis``, best first) of the photo ``lab`` (H, W, 3) with
    the best one's ``flat`` measured (``flat_share``), and "no floor visible" (the bottom
    border, NONE) put first when it separates nothing along most of its length
    (``separates_nothing``): a blank wall's paint on both sides of it. "No floor visible"
    takes the best one's score and place; the others follow in their order (a NONE among
    them moves up), at most ``max_n``."""
    if not hyps:
        return hyps
    H, W = lab.shape[:2]
    best = replace(hyps[0], flat=flat_share(lab, hyps[0].polyline, hyps[0].kinds))
    if not separates_nothing(best.flat):
        return [best, *hyps[1:]]
    none = replace(best, polyline=np.array([[0.0, H - 0.5], [W - 1.0, H - 0.5]]),
                   kinds=np.array([SegKind.NONE]), support=0.0, flat=0.0)
    rest = [h for h in (best, *hyps[1:]) if not np.all(h.kinds == SegKind.NONE)]
    return [none, *rest][:max_n]
