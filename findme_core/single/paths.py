"""Paths of the boundary search (``search.best_paths``) turned into what the ranking and the
user need: the polyline in pixels with its segment kinds, and the per-column rows and
additive features of many paths at once.

A path is (score, start track, chain of event indices left to right) over the tracks of
``search`` (N candidate lines, then TOP = N, BOTTOM = N + 1). Its pieces are the column
ranges [k0, k1) between its events, on one track each; they tile [0, W).
"""

from __future__ import annotations

from itertools import chain

import numpy as np

from findme_core.single.search import ADDITIVE, Events, SegKind


def path_polyline(start: int, chain: tuple[int, ...], ev: Events, coef: np.ndarray,
                  width: int, height: int) -> tuple[np.ndarray, np.ndarray, list[int]]:
    """Vertices (M, 2), segment kinds (M - 1,) and the track of each segment (-1 for a step).

    Corners are exact line intersections; a step is drawn as a near-vertical segment 0.5 px
    wide at the foot column of its vertical edge; TOP is the row -0.5, BOTTOM the row H - 0.5.
    """
    n = len(coef)
    seg_kind = {n: SegKind.OPEN, n + 1: SegKind.NONE}

    def row(t, u):
        if t >= n:
            return -0.5 if t == n else height - 0.5
        return -(coef[t, 0] * u + coef[t, 2]) / coef[t, 1]

    track = start
    pts = [(0.0, row(track, 0.0))]
    kinds: list[int] = []
    tracks: list[int] = []
    for e in chain:
        d = int(ev.dst[e])
        u = float(ev.u[e])
        here = seg_kind.get(track, SegKind.WALL)
        if ev.step[e]:
            pts += [(u - 0.25, row(track, u)), (u + 0.25, row(d, u))]
            kinds += [here, SegKind.STEP]
            tracks += [track, -1]
        else:
            pts.append((u, row(track, u) if d >= n else row(d, u)))
            kinds.append(here)
            tracks.append(track)
        track = d
    pts.append((width - 1.0, row(track, width - 1.0)))
    kinds.append(seg_kind.get(track, SegKind.WALL))
    tracks.append(track)
    pts = np.array(pts)
    # events in one column are ordered by column boundary, not by their exact u
    pts[:, 0] = np.maximum.accumulate(np.clip(pts[:, 0], 0.0, width - 1.0))
    kinds = np.array(kinds, dtype=int)
    # two events at one point leave a zero-length segment: drop it
    keep = np.ones(len(kinds), bool)
    keep[np.all(np.abs(np.diff(pts, axis=0)) < 1e-9, axis=1)] = False
    if not keep.all() and keep.any():
        pts = np.vstack([pts[:1], pts[1:][keep]])
        kinds, tracks = kinds[keep], [t for t, k in zip(tracks, keep) if k]
    return pts, kinds, tracks


def path_pieces(paths, ev: Events, width: int):
    """Flatten paths into pieces.

    Args:
        paths: sequence of (score, start track, event chain).
    Returns:
        (piece_path, piece_track, k0, k1) arrays over all pieces (column boundaries
        [k0, k1)), and (K, 2) counts of corners / crossings and of steps per path.
        The pieces of each path are consecutive, left to right, and cover [0, width).
    """
    K = len(paths)
    n_ev = np.fromiter((len(p[2]) for p in paths), int, K)
    flat = np.fromiter(chain.from_iterable(p[2] for p in paths), int, int(n_ev.sum()))
    starts = np.fromiter((p[1] for p in paths), int, K)
    n_pc = n_ev + 1
    first = np.cumsum(n_pc) - n_pc                      # index of each path's first piece
    pp = np.repeat(np.arange(K), n_pc)
    is_first = np.zeros(len(pp), bool)
    is_first[first] = True
    is_last = np.zeros(len(pp), bool)
    is_last[first + n_ev] = True
    pt = np.empty(len(pp), int)
    pt[is_first] = starts
    pt[~is_first] = ev.dst[flat]
    a = np.zeros(len(pp), int)
    a[~is_first] = ev.col[flat]
    b = np.full(len(pp), width)
    b[~is_last] = ev.col[flat]
    counts = np.zeros((K, 2))
    if len(flat):
        np.add.at(counts, (np.repeat(np.arange(K), n_ev), ev.step[flat].astype(int)), 1)
    return pp, pt, a, b, counts


def path_features(pieces, F: np.ndarray, n_paths: int) -> np.ndarray:
    """(K, len(ADDITIVE) + 2) features of K paths: the additive sums (``track_tables``) over
    their pieces, then the numbers of corners / crossings and of occluding steps."""
    pp, pt, a, b, counts = pieces
    d = F[:, pt, b] - F[:, pt, a]                       # (len(ADDITIVE), pieces)
    out = np.zeros((n_paths, len(ADDITIVE)))
    np.add.at(out, pp, d.T)
    return np.column_stack([out, counts])


def path_rows(pieces, rows: np.ndarray, n_paths: int) -> np.ndarray:
    """(K, W) boundary row of each path at every column, from the track rows (N + 2, W)."""
    _, pt, a, b, _ = pieces
    W = rows.shape[1]
    track = np.repeat(pt, b - a).reshape(n_paths, W)   # pieces tile [0, W) path by path
    return rows[track, np.arange(W)[None, :]]
