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
    lines = np.asarray(coef).tolist()   # Python floats: the same IEEE operations as numpy's
    ev_at = list(chain)                 # scalars, without their overhead

    def row(t, u):
        if t >= n:
            return -0.5 if t == n else height - 0.5
        a, b, c = lines[t]
        return -(a * u + c) / b

    track = start
    pts = [(0.0, row(track, 0.0))]
    kinds: list[int] = []
    tracks: list[int] = []
    for d, u, step in zip(ev.dst[ev_at].tolist(), ev.u[ev_at].astype(float).tolist(),
                          ev.step[ev_at].tolist()):
        here = seg_kind.get(track, SegKind.WALL)
        if step:
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
    # events in one column are ordered by column boundary, not by their exact u: the
    # columns clipped to the image and made non-decreasing (np.clip, np.maximum.accumulate
    # on a dozen finite Python floats)
    xs, run, hi = [], -np.inf, width - 1.0
    for x, _ in pts:
        x = min(max(x, 0.0), hi)
        run = x if x > run else run
        xs.append(run)
    ys = [y for _, y in pts]
    # two events at one point leave a zero-length segment: drop it
    keep = [not (abs(xs[i + 1] - xs[i]) < 1e-9 and abs(ys[i + 1] - ys[i]) < 1e-9)
            for i in range(len(kinds))]
    if not all(keep) and any(keep):
        at = [0] + [i + 1 for i, k in enumerate(keep) if k]
        xs, ys = [xs[i] for i in at], [ys[i] for i in at]
        kinds = [s for s, k in zip(kinds, keep) if k]
        tracks = [t for t, k in zip(tracks, keep) if k]
    pts = np.array([xs, ys], float).T.copy()
    kinds = np.array(kinds, dtype=int)
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
