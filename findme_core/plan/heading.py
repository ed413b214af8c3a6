"""The phone's heading: which way each photo looked, turned about gravity, as the phone's
orientation sensor measured it when the photo was taken.

Photos that share nothing (a turn split in two halves, turns wider than the field of view)
can fit a symmetric room's walls at two or four headings: a rectangle's half-turn twin agrees
with the walls seen as well as the truth does, and only the truth is right. The photos cannot
tell; the phone can. Its heading (a compass bearing, or the yaw its gyroscope integrated since
the page started listening: only differences between a session's photos are used) rules out
the candidate poses that turn a block away from what the phone measured.

Frames and units: a heading is the bearing of the camera's optical axis projected on the
level plane, radians, growing as the camera turns right seen from above (the plan's yaw
convention, ``fuse``); its 1-sigma in radians; its reference, a short label of what it is
measured from ("" the phone page's sensor, whose zero is its own; "T" / "M" a photo file's
compass bearing from true / magnetic north, "?" when it does not say). A photo's room yaw
is its heading minus one offset per reference, so the yaw between two photos i, j of one
reference should equal h_j - h_i; headings of different references are never compared.
Pure numpy; no I/O.
"""

from __future__ import annotations

import math

import numpy as np

from findme_core.errors import InputError
from findme_core.geometry.planar import wrap

#: a heading's 1-sigma must lie in (0, MAX_SIGMA_RAD]: a wider one tells nothing a room's
#: symmetry does not (its twins lie 90 deg apart)
MAX_SIGMA_RAD = math.radians(90.0)


def check(heading) -> tuple[float, float, str] | None:
    """A photo's (heading, 1-sigma, reference), radians, validated, from (heading, 1-sigma)
    (reference "") or (heading, 1-sigma, reference); None stays None.

    Raises:
        InputError: not two finite numbers and an optional str, or a 1-sigma outside
            (0, ``MAX_SIGMA_RAD``].
    """
    if heading is None:
        return None
    three = isinstance(heading, (tuple, list)) and len(heading) == 3
    ref = heading[2] if three else ""
    try:
        h = np.asarray(heading[:2] if three else heading, float).ravel()
    except (TypeError, ValueError):
        h = np.zeros(0)
    if h.shape != (2,) or not np.all(np.isfinite(h)) or not isinstance(ref, str):
        raise InputError("a heading is two finite numbers (radians, 1-sigma) and an optional "
                         f"reference label, got {heading!r}")
    if not 0.0 < h[1] <= MAX_SIGMA_RAD:
        raise InputError(f"a heading's 1-sigma must lie in (0, {MAX_SIGMA_RAD:.4f}] rad, got "
                         f"{h[1]!r}")
    return float(wrap(h[0])), float(h[1]), ref


def table(headings) -> np.ndarray | None:
    """(N, 3) (heading, 1-sigma, reference number) per photo, NaN rows where the phone gave
    none, from N ``check``-able entries (None: none); the reference number counts the
    distinct references in order of first use. None when no photo has one."""
    rows = [check(h) for h in headings]
    if all(r is None for r in rows):
        return None
    refs = list(dict.fromkeys(r[2] for r in rows if r is not None))
    return np.array([(np.nan,) * 3 if r is None else (r[0], r[1], refs.index(r[2]))
                     for r in rows], float)


def fits(headings, poses, rel, placed, members, cands, gate: float) -> np.ndarray:
    """(C,) whether each candidate pose of a block turns it as the phone says.

    For each (placed photo p, block photo i) pair where both have a heading of one
    reference, the candidate's turn from p to i, (yaw + rel[i]) - yaw_p, is compared with
    h_i - h_p; its error over hypot(sigma_i, sigma_p) is the pair's z. A candidate fits when
    the median z over the pairs is at most ``gate`` (one bad reading does not overrule the
    others). Every candidate fits when no pair has both headings of one reference.

    Args:
        headings: (N, 3) (heading, 1-sigma, reference number) per photo, NaN where unknown
            (``table``), or None.
        poses: (N, 3) room-frame poses (NaN rows: not placed); rel: (N,) yaw of each photo
            in its block (radians); placed, members: indices of the placed photos and of the
            block's; cands: (C, 3) block poses (x, z, yaw of the block's first photo).
    """
    ok = np.ones(len(cands), bool)
    if headings is None or not len(cands):
        return ok
    known = np.isfinite(headings[:, 0])
    ps = [p for p in placed if known[p]]
    ms = [i for i in members if known[i]]
    if not ps or not ms:
        return ok
    z = []
    for p in ps:
        for i in ms:
            if headings[i, 2] != headings[p, 2]:
                continue
            turn = cands[:, 2] + rel[i] - poses[p, 2]
            err = wrap(turn - (headings[i, 0] - headings[p, 0]))
            z.append(np.abs(err) / math.hypot(headings[i, 1], headings[p, 1]))
    return np.median(np.array(z), axis=0) <= gate if z else ok
