"""A boundary that separates nothing, or runs over no floor: where the photo is the same
colour just above and just below it, or, in a photo that looks across the room, smooth just
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

A level photo of a kitchen counter shows no floor either: the counter top meets the wall
below the horizon, as a floor would, and the best boundary follows that edge (or a sill's):
as a floor line it puts the wall 1.5-3x too far (a counter 0.9 m up, the camera 1.4 m), the
answers confident and wrong (dev kitchen zr_r06, README "Kitchens"). What lies under it is
a counter top, a sill or the painted wall below one: smooth, where a floor seen across a
room has the texture of its carpet, boards or tiles. ``smooth_share`` measures, over the same
strips, the share where the band under the boundary (``support.EdgeField.band_texture``:
mean gradient, grey levels per pixel) is smoother than the search's ``smooth_texture`` (1.0,
hand-set for the same surfaces: ``search.SearchParams``); ``runs_over_no_floor``: half of
them or more, in a photo whose horizon is in view (``segments.horizon_top_row`` > 0). A
photo looking down at the floor is not judged: a smooth floor (TUM's linoleum, 0.4-0.8) is
then the rule, and a counter's edge does not pose as its boundary. The constants are the
search's and ``FLAT_SHARE``'s, not fitted. Checked 2026-12-02 on the dev split (dataset's
gravity): 16 of the 123 photos with the horizon in view (all ZInD) have a smooth share of
half or more, and 311 of their 787 answers were beyond 3 sigma (4 % in the other ZInD
photos). 10 show no floor at all (9 kitchen counters, 1 window sill); the other 6 show a
sliver of it (2-4 % of the photo: a counter's front, a sill above the floor), 64 of their
422 answers beyond 3 sigma, now unanswered too. The highest share of the other photos is
0.48: a carpet whose boundary is right, the margin this test has.

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
#: rows between the boundary and the band whose texture is measured, and the band's rows
#: (pixels at the working size; passed to the texture, ``support.EdgeField.band_texture``)
TEXTURE_OFFSET, TEXTURE_BAND = 3, 24


def flat_share(lab: np.ndarray, poly, kinds) -> float:
    """Share in [0, 1] of the boundary's measured WALL strips across which the colour does
    not step (0 when fewer than ``MIN_COLUMNS`` are measured). ``lab``: (H, W, 3) uint8, the
    photo cut into strips of ``COLUMN_STEP`` columns; ``poly`` (M, 2), ``kinds`` (M - 1,) as
    a ``Hypothesis``'s; a strip's boundary row is the polyline's at its centre, rounded."""
    H, W = lab.shape[:2]
    x0, _, vs = _strips(poly, kinds, W, H, GAP + BAND, GAP + BAND)
    v = np.rint(vs).astype(int)
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


def _strips(poly, kinds, width: int, height: int, margin_above: int, margin_below: int):
    """Each ``COLUMN_STEP``-wide strip of a ``width`` x ``height`` photo over a WALL segment of
    the boundary (``poly`` (M, 2), ``kinds`` (M - 1,)) with ``margin_above`` rows above the
    boundary and ``margin_below`` below it inside the photo: (C,) first columns, (C,) centre
    columns, (C,) boundary rows there (the polyline's, unrounded)."""
    poly = np.asarray(poly, float)
    kinds = np.asarray(kinds)
    x0 = COLUMN_STEP * np.arange(width // COLUMN_STEP)
    us = x0 + (COLUMN_STEP - 1) / 2.0
    seg = np.clip(np.searchsorted(poly[:, 0], us, side="right") - 1, 0, len(kinds) - 1)
    vs = np.interp(us, poly[:, 0], poly[:, 1])
    ok = (kinds[seg] == SegKind.WALL) & (vs >= margin_above) & (vs < height - margin_below)
    return x0[ok], us[ok], vs[ok]


def smooth_share(texture, top_row: int, poly, kinds, width: int, height: int,
                 smooth: float) -> float:
    """Share in [0, 1] of the boundary's WALL strips under which the photo is smoother than
    ``smooth`` (grey levels per pixel); 0 when the photo's horizon is not in view
    (``top_row``, ``segments.horizon_top_row``, is 0) or fewer than ``MIN_COLUMNS`` strips
    are measured. ``texture``: (rows (K,), columns (K,), offset, band) -> (K,) mean gradient
    of the ``band`` rows ``offset`` rows under each (``support.EdgeField.band_texture``;
    ``TEXTURE_OFFSET``, ``TEXTURE_BAND``); ``poly`` (M, 2),
    ``kinds`` (M - 1,) as a ``Hypothesis``'s, of a ``width`` x ``height`` photo."""
    if top_row <= 0:
        return 0.0
    _, us, vs = _strips(poly, kinds, width, height, 0, TEXTURE_OFFSET + TEXTURE_BAND)
    if len(us) < MIN_COLUMNS:
        return 0.0
    t = np.asarray(texture(vs, np.rint(us).astype(int), TEXTURE_OFFSET, TEXTURE_BAND), float)
    return float(np.count_nonzero(t < smooth)) / len(us)


def separates_nothing(share: float) -> bool:
    """Whether a boundary with ``flat_share`` ``share`` separates nothing along most of it."""
    return share >= FLAT_SHARE


def runs_over_no_floor(share: float) -> bool:
    """Whether a boundary with ``smooth_share`` ``share`` runs over a smooth band along most
    of it: a counter top, a sill, a wall (``FLAT_SHARE``: a half, a meaning)."""
    return share >= FLAT_SHARE


def no_floor_first(hyps: list, lab: np.ndarray, max_n: int, texture=None, top_row: int = 0,
                   smooth: float = 1.0) -> list:
    """``hyps`` (``hypotheses.Hypothesis``, best first) of the photo ``lab`` (H, W, 3) with
    the best one's ``flat`` and ``smooth`` measured (``flat_share``; ``smooth_share`` with
    ``texture``, ``top_row`` and ``smooth`` as it takes them, 0 without ``texture``), and "no
    floor visible" (the bottom border, NONE) put first when it separates nothing along most
    of its length (``separates_nothing``: a blank wall's paint on both sides of it) or runs
    over no floor (``runs_over_no_floor``: a counter top under it). "No floor visible" takes
    the best one's score and place; the others follow in their order (a NONE among them
    moves up), at most ``max_n``."""
    if not hyps:
        return hyps
    H, W = lab.shape[:2]
    h = hyps[0]
    best = replace(h, flat=flat_share(lab, h.polyline, h.kinds),
                   smooth=0.0 if texture is None else smooth_share(
                       texture, top_row, h.polyline, h.kinds, W, H, smooth))
    if not separates_nothing(best.flat) and not runs_over_no_floor(best.smooth):
        return [best, *hyps[1:]]
    none = replace(best, polyline=np.array([[0.0, H - 0.5], [W - 1.0, H - 0.5]]),
                   kinds=np.array([SegKind.NONE]), support=0.0, flat=0.0, smooth=0.0)
    rest = [h for h in (best, *hyps[1:]) if not np.all(h.kinds == SegKind.NONE)]
    return [none, *rest][:max_n]
