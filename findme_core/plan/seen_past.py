"""Outline walls the photos saw past: floor, and a wall's base a little further out, seen
through a wall the outline put there.

A photo that sees a wall's base sees the floor up to it. When the room's outline puts a wall
in front of such a sample, the photo saw through that wall. Through a door that is normal,
but only over a door's width, and another room's walls lie further behind. A wall seen
``behind_m`` (0.3-1.0 m) behind an outline wall, over more than ``min_m`` of it, means
the outline stands where no wall is. The usual cause is one line fitted to wrong samples
that cut a corner off or ran through the room.

What is done about it (``dropped``):

* the outline's line was seen from ONE spot only, and photos of another spot saw past it
  along more than half of the outline's wall (``share``, at least ``min_drop_m``; or
  ``min_m``): its photos, all taken from one place, saw one boundary wrong alike. The line
  is dropped and the outline drawn again (``outline``). In a rendered 5 x 4 m room, one
  photo whose boundary cuts across a corner cut that corner off the plan (5 of 8 photos of
  a spot, each alone); with gravity withheld, dev room zr_r07 lost a 2.9 x 0.7 m slice to a
  line two photos of one spot saw (IoU 0.78). Dropped, both come out right (IoU 0.96);
* a line seen from several spots that the photos saw past is not dropped: the photos
  disagree about the room. ``consistency.check`` refuses the plan with the reason.

Frames and units as ``floorplan``: the room frame's (x, z), metres. Pure numpy; no I/O.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from findme_core.errors import GeometryError
from findme_core.plan import polygon, wall_kinds, walls


@dataclass(frozen=True)
class SeenPastParams:
    """Attributes:
        behind_m: (near, far): a wall's base seen this far behind an outline wall, through
            it. Nearer is the wall itself (the outline smooths dents thinner than
            ``polygon.PolygonParams.detail_m``, 0.3 m). Farther is another room's wall seen
            through a door.
        min_m: seen past along more of the wall than this: twice a door's width (a closet's
            double door is ~1.5-1.8 m). Not fitted. On the dev rooms (2026-11-30) the right
            plans were seen past along at most 0.5 m and the wrong ones along 2.8-3.8 m, so
            any value from 1.5 to 2.8 m decides alike.
        share, min_drop_m: a line one spot saw is dropped when seen past along more than
            this share of the outline's wall and more than this (or ``min_m``).
        bin_m: each sample stands for this much of the wall's length.
        max_redraws: the outline is drawn again at most this many times.
    """

    behind_m: tuple = (0.3, 1.0)
    min_m: float = 2.0
    bin_m: float = 0.1
    share: float = 0.5
    min_drop_m: float = 0.5
    max_redraws: int = 3


def wall_lengths(vertices: np.ndarray) -> np.ndarray:
    """(V,) length of each outline wall k (vertex k to k + 1, closing), metres."""
    P = np.asarray(vertices, float).reshape(-1, 2)
    return np.hypot(*(np.roll(P, -1, axis=0) - P).T)


def seen_through(vertices: np.ndarray, points: np.ndarray, cams: np.ndarray,
                 params: SeenPastParams = SeenPastParams()) -> tuple[np.ndarray, list]:
    """How much of each outline wall the photos saw past.

    Args:
        vertices: (V, 2) outline vertices (x, z), metres, either orientation; wall k runs
            from vertex k to k + 1.
        points: (S, 2) wall-base samples the photos saw (``walls.Evidence.points``).
        cams: (S, 2) the camera each sample was seen from.
    Returns:
        ((V,) the length of wall k, metres, behind which a sample lies ``behind_m`` further
        out, its ray from a camera on the room's side crossing wall k, each sample standing
        for ``bin_m`` along it; [V] int arrays, the indices of those samples). Zeros for a
        degenerate outline (< 3 vertices or no area), no samples, and zero-length walls.
    """
    P = np.asarray(vertices, float).reshape(-1, 2)
    p = np.asarray(points, float).reshape(-1, 2)
    c = np.asarray(cams, float).reshape(-1, 2)
    V = len(P)
    length, which = np.zeros(V), [np.zeros(0, int) for _ in range(V)]
    area = polygon.area(P) if V >= 3 else 0.0
    if abs(area) < 1e-9 or not len(p):
        return length, which
    near, far = params.behind_m
    for k, L in enumerate(wall_lengths(P)):
        if L < 1e-9:
            continue
        a, u = P[k], (P[(k + 1) % V] - P[k]) / L
        n = np.sign(area) * np.array([u[1], -u[0]])     # outward: right of u when CCW
        s, dn = (p - a) @ u, (p - a) @ n
        sc, dc = (c - a) @ u, (c - a) @ n
        with np.errstate(divide="ignore", invalid="ignore"):
            cross = sc + dc / (dc - dn) * (s - sc)      # where the ray meets the wall's line
        m = np.flatnonzero((dn > near) & (dn < far) & (dc < 0) & (cross >= 0) & (cross <= L)
                           & (s >= 0) & (s <= L))
        length[k] = _covered(s[m], params.bin_m / 2, L)
        which[k] = m
    return length, which


def _covered(s: np.ndarray, h: float, L: float) -> float:
    """Length of [0, L] within ``h`` of a place in ``s`` (metres; continuous in ``s``: no
    count of bins that a last-bit difference could change)."""
    if not len(s):
        return 0.0
    s = np.sort(s)
    total = 2 * h + float(np.sum(np.minimum(np.diff(s), 2 * h)))
    return total - max(0.0, h - s[0]) - max(0.0, s[-1] + h - L)


def dropped(out: polygon.Outline, ev: walls.Evidence, wl: walls.WallLines, spot,
            params: SeenPastParams = SeenPastParams()) -> np.ndarray:
    """Indices into ``wl`` of the wall lines to drop (module docstring): an outline wall
    seen past along more than min(``min_m``, ``share`` of it) and ``min_drop_m``, on a
    line that photos of one spot alone saw, and seen past by photos of another spot.
    ``out``: the outline drawn on ``Lines.of(wl)``; ``spot``: (N,) each photo's spot."""
    spot = np.asarray(spot)
    length, which = seen_through(out.vertices, ev.points, ev.cams[ev.photo], params)
    need = np.maximum(np.minimum(params.min_m, params.share * wall_lengths(out.vertices)),
                      params.min_drop_m)
    drop = []
    for k in np.flatnonzero((length > need) & (out.line >= 0)):
        li = int(wl.walls[out.line[k]])
        own = np.unique(spot[ev.photo[wl.sample_line == li]])
        past = np.unique(spot[ev.photo[which[k]]])
        if len(own) == 1 and np.any(past != own[0]):
            drop.append(li)
    return np.unique(np.array(drop, int))


def outline(layouts, poses: np.ndarray, params, spot=None):
    """(evidence, classified lines, outline, which outline lines are on the axes) of N
    photos' layouts at poses (N, 3), drawn again without the lines ``dropped`` gives (kind
    "seen past") while there are any, at most ``max_redraws`` times; the last outline
    drawn when one without them cannot be. ``params``: a ``floorplan.PlanParams``;
    ``spot``: (N,) spot labels (default: one per photo).

    Raises:
        GeometryError: no outline at all (``polygon.outline``).
    """
    spot = np.arange(len(poses)) if spot is None else spot
    ev = walls.evidence(layouts, poses)
    wl = wall_kinds.classify(ev, walls.fit(ev, params.lines), params.lines)
    cams = poses[np.isfinite(poses[:, 0]), :2]
    anchor = cams.mean(0) if len(cams) else np.zeros(2)
    drawn = None
    for _ in range(params.seen_past.max_redraws + 1):
        lines = polygon.Lines.of(wl)
        try:
            out = polygon.outline(lines, polygon.free_space(layouts, poses, lines, params.polygon),
                                  params.polygon, anchor)
        except GeometryError:
            if drawn is None:
                raise
            break                  # without the dropped lines no outline: keep the last one
        snapped = (wl.snapped[wl.walls] if wl.snapped is not None
                   else np.zeros(len(lines.normals), bool))
        drawn = (ev, wl, out, snapped)
        drop = dropped(out, ev, wl, spot, params.seen_past)
        if not len(drop):
            break
        kind = wl.kind.copy()
        kind[drop] = "seen past"
        wl = replace(wl, kind=kind)
    return drawn
