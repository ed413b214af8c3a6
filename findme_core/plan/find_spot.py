"""Find me with a session's photos: where one or more new photos, taken at one place (a
user turning round), were taken in a placed session's room frame.

The new photos join the session as one more spot: the photos joined by rotation-only links
(``spot.rotation_yaw``) form blocks; the block with the most layouts is placed as
``fuse.place`` places a block of a new spot (candidates from its layouts against every
placed photo's and from its two-photo motions, scored by the layouts, the feature matches and
the motions; 3 DOF), and every other block then turns in place at each candidate position
(1 DOF), its best score adding to the candidate's.
More photos from one place see more of the room: more walls to register and more matches.

Frames: the room frame of ``fuse`` (x, z metres; yaw radians, > 0 turned right); a pose
(x, z, yaw) maps a floor point p of the photo's level frame to R(yaw) p + (x, z). Pure
numpy; no I/O.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from findme_core.errors import GeometryError
from findme_core.geometry import ties
from findme_core.geometry.planar import wrap
from findme_core.plan import fuse


def place(layouts, poses, new_layouts, links=(), matches=None, motions=(),
          params: fuse.FuseParams = fuse.FuseParams(),
          headings=None) -> tuple[np.ndarray, np.ndarray]:
    """Where K new photos taken at one place are in the room frame of N placed photos.

    Args:
        layouts: N layouts of the placed photos (None: none); poses: (N, 3) their poses in
            the room frame (NaN rows: not placed).
        new_layouts: K layouts of the new photos (None: none), indices N .. N + K - 1.
        links: ``fuse.Link`` rotation-only yaws between new photos (indices N ..).
        matches: {(i, j): (a (M, 3), b (M, 3))} level bearings of the feature matches of a
            placed photo i and a new photo j.
        motions: ``fuse.Link`` (i, j, yaw, sigma, t): new photo j's pose in placed photo i's
            level frame.
        headings: (N + K, 3) each photo's heading (``heading.table``: placed photos first),
            or None: a candidate that turns the new photos away from what the phone
            measured is not tried (``heading.fits``), as in a plan.

    Returns:
        (poses (C, K, 3), scores (C,)): per candidate (clearly different poses of the
        block with the most layouts: a symmetric room gives several), the pose of every new
        photo, best total score first; NaN rows for photos that share no rotation link with
        that block and could not be turned in place.

    Raises:
        GeometryError: no new photo, or none can be placed (no layout, no wall in common),
            with the reason.
    """
    # the matches scored sharply (MSAC): nothing refines a found photo's pose after, so its
    # candidate must be the best aligned one (a plan's placement is refined: ``fuse``)
    params = replace(params, feature_fade_px=0.0)
    n, k = len(layouts), len(new_layouts)
    if k == 0:
        raise GeometryError("no new photo to find")
    L = list(layouts) + list(new_layouts)
    P = np.vstack([np.asarray(poses, float).reshape(n, 3), np.full((k, 3), np.nan)])
    local = [fuse.Link(m.i - n, m.j - n, m.yaw, m.sigma) for m in links
             if min(m.i, m.j) >= n and max(m.i, m.j) < n + k]
    nb, rel_new = fuse.blocks(k, local)
    block = np.concatenate([np.arange(n), n + nb])
    rel = np.concatenate([np.zeros(n), rel_new])
    spot = np.concatenate([np.arange(n), np.full(k, n)])   # the new photos: one place
    has = np.array([x is not None for x in new_layouts])
    sizes = np.bincount(nb, weights=has, minlength=int(nb.max()) + 1)
    first = n + int(np.argmax(sizes))
    r = fuse.place_block(L, P, rel, block, spot, {}, matches, motions, first, params, headings)
    if isinstance(r, str):
        raise GeometryError(r)
    cands, scores = r
    out, total = np.full((len(cands), k, 3), np.nan), np.array(scores, float)
    others = [b for b in np.unique(block[n:]) if b != first]
    for c, pose in enumerate(cands):
        Q = P.copy()
        for i in np.flatnonzero(block == first):
            Q[i] = (pose[0], pose[1], wrap(pose[2] + rel[i]))
        for b in others:     # a block the turn did not link: it turns in place, and its
            rb = fuse.place_block(L, Q, rel, block, spot, {n: pose[:2]}, matches, motions,
                                  b, params, headings)   # agreement counts for the candidate
            if not isinstance(rb, str):
                total[c] += rb[1][0]
                for i in np.flatnonzero(block == b):
                    Q[i] = (rb[0][0, 0], rb[0][0, 1], wrap(rb[0][0, 2] + rel[i]))
        out[c] = Q[n:]
    o = ties.order(total)   # candidates that score alike (a symmetric room): in their order
    return out[o], total[o]

