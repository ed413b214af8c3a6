"""Search for ground-wall boundary polylines over candidate lines (our method).

A boundary runs from the left image border to the right border over pieces of *tracks*:
the N candidate floor lines plus two virtual tracks: ``TOP`` (track N: the floor continues
past the top image border, every pixel of the column is floor) and ``BOTTOM`` (track N + 1:
no floor in the column; across the whole width it is the answer "no floor visible"). It
moves from track to track at *events*,
each at a column:

* corner: two floor lines intersect at the image of a floor point (a room corner);
* step: an occluding vertical edge (a 3D vertical line, which the paper discards) stands on
  one line at its foot, and the boundary jumps there to a farther line or to TOP (furniture
  in front of a wall, a wall corner occluding another wall);
* crossing: a floor line leaves through the top border (the floor continues beyond it) or
  the bottom border (a near wall hides the floor).

Every track has a cumulative reward ``A[t, k]`` over column boundaries k = 0..W
(edge support minus a cost per unit of unsupported length and per column outside the image;
columns where a line is at or above the horizon are forbidden). The score of a path is the
sum of its pieces' rewards minus its events' costs. One forward and one backward pass over
the events sorted by column give, for every event, the best path through it; those paths and
the single lines spanning the image are the candidates. Each pass is O(number of events).
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import IntEnum

import numpy as np

from findme_core.geometry import ties
from findme_core.geometry.camera import Camera
from findme_core.single.support import SupportTable

NEG = -1e18
FORBIDDEN = 1e6  # reward per column where a track is not a floor boundary
#: Two path values closer than ``TIE_ABS + TIE_REL * magnitude`` are a tie, decided by the
#: order the events are met (then by candidate index), not by last-bit differences of the
#: rewards (BLAS kernels, CPU features). Values carry their tracks' cumulative FORBIDDEN
#: offsets (up to W * FORBIDDEN, 6.4e8 at 640 px), whose rounding TIE_REL covers (45 ulps);
#: path scores are O(1), whose kernel noise (~1e-14) TIE_ABS covers. The smallest real
#: difference seen between two dev paths is 2e-10.
TIE_ABS, TIE_REL = 1e-11, 1e-14


class SegKind(IntEnum):
    """Kind of each polyline segment (between consecutive vertices)."""

    WALL = 0  # ground-wall boundary on a floor line: a wall (or object face) stands on it
    STEP = 1  # occluding edge: the boundary jumps between a nearer and a farther surface
    OPEN = 2  # floor continues past the top image border: no wall seen in these columns
    NONE = 3  # no floor in these columns (along the bottom border)


#: Additive features: summed along a path from cumulative per-column tables.
ADDITIVE = ("support", "length", "outside", "top", "bottom", "region", "far")


@dataclass(frozen=True)
class SearchParams:
    step_foot_tol_px: float = 6.0   # a vertical edge's foot must lie this close to its line
    step_min_jump_px: float = 15.0
    min_vertical_px: float = 25.0
    horizon_margin: float = 0.01
    far_deg: float = 6.0   # a boundary seen less than this below the horizon is implausibly far
    smooth_texture: float = 1.0  # ... when the band below it is this smooth (grey levels / px:
                                 # a counter top, a sill, a wall; camera noise), and not at all
    ground_texture: float = 2.5  # when it is this textured (ground at a grazing angle: grass,
                                 # asphalt, paving; a street, where far boundaries are the rule)


@dataclass(frozen=True)
class Events:
    src: np.ndarray    # (E,) track before the event
    dst: np.ndarray    # (E,) track after
    col: np.ndarray    # (E,) column boundary k in 1..W-1
    u: np.ndarray      # (E,) exact column of the event
    step: np.ndarray   # (E,) bool: occluding step (else corner / crossing)


def track_rows(table: SupportTable, height: int) -> np.ndarray:
    """(N + 2, W) row of every track per column (TOP = -0.5, BOTTOM = height - 0.5)."""
    W = table.v.shape[1]
    return np.vstack([table.v, np.full((1, W), -0.5), np.full((1, W), height - 0.5)])


def track_tables(table: SupportTable, camera: Camera, p: SearchParams,
                 region: np.ndarray | None = None, valid: np.ndarray | None = None,
                 front: np.ndarray | None = None,
                 texture: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Cumulative additive features of every track and per-column validity.

    Args:
        table: support of the N candidate lines.
        region: optional (N + 2, W) colour reward per column of the floor region each track
            implies (``appearance.FloorLikelihood.below`` of the track rows).
        valid: the validity returned by an earlier call on the same table (not recomputed).
        front: (N,) bool, the lines that run across the view (``lines.LineKind.FRONT``):
            only those count as far (default all). A wall facing the camera stands at one
            distance along its base, so a front line just below the horizon means a wall
            implausibly far away (the edge of a counter top or a window sill seen level);
            a receding line's far end approaches the horizon in any room or street.
        texture: function (rows (K,), columns (K,)) -> (K,) gradient magnitude of the band
            just below those line rows (``support.EdgeField.band_texture``), asked only
            where a line is far: a far line with textured ground below it
            (grass, asphalt, paving: a street, where a far boundary is the rule) does not
            count as far: farness is scaled from 1 at ``smooth_texture`` (counter tops,
            sills and the walls below them are smooth) down to 0 at ``ground_texture``.
    Returns:
        F: (len(ADDITIVE), N + 2, W + 1) cumulative sums over column boundaries, in pixels
            (support and length: arc length; outside / top / bottom: columns; region: the
            per-column reward; far: ``farness`` of a line's floor point in each column).
        valid: (N + 2, W) bool, the track is a possible floor boundary in that column.
    """
    W = camera.width
    if valid is None:
        rows = track_rows(table, camera.height)
        u = np.broadcast_to(np.arange(W, dtype=float), rows.shape)
        valid = camera.below_horizon(np.column_stack([u.ravel(), rows.ravel()]),
                                     p.horizon_margin).reshape(rows.shape)
        valid[-1] = True  # "no floor here" is always a possible answer
    n = len(table.S)
    F = np.zeros((len(ADDITIVE), n + 2, W + 1))
    F[0, :n], F[1, :n], F[2, :n] = table.S, table.L, table.O
    cols = np.arange(W + 1, dtype=float)
    F[3, n], F[4, n + 1] = cols, cols
    far = farness(table.v, camera, p.far_deg)
    if front is not None:
        far[~np.asarray(front, bool)] = 0.0
    if texture is not None:
        i, u = np.nonzero(far > 0)
        if len(i):
            t = texture(table.v[i, u], u)
            far[i, u] *= np.clip((p.ground_texture - t) / (p.ground_texture - p.smooth_texture),
                                 0.0, 1.0)
    F[6, :n, 1:] = np.cumsum(far, axis=1)
    if region is not None:
        F[5, :, 1:] = np.cumsum(region, axis=1)
    return F, valid


def with_region(F: np.ndarray, region: np.ndarray) -> np.ndarray:
    """A copy of the tables ``F`` (``track_tables``) with the colour reward (N + 2, W) of
    each track's floor region."""
    out = F.copy()
    out[5, :, 1:] = np.cumsum(region, axis=1)
    return out


def farness(rows: np.ndarray, camera: Camera, far_deg: float) -> np.ndarray:
    """(N, W) in [0, 1] for line rows (N, W) at columns 0..W-1: how implausibly far the
    floor point of each pixel is, ``clip(1 - sin(d) / sin(far_deg), 0, 1)`` for its
    depression d below the horizon (a wall at distance D from a camera at height h has its
    base atan(h / D) below the horizon: 6 deg is ~13 m from 1.4 m). Scale-free: no camera
    height needed. 1 at and above the horizon."""
    u = np.arange(rows.shape[1], dtype=float)[None, :]
    x, y = (u - camera.cx) / camera.fx, (rows - camera.cy) / camera.fy
    R = camera.R_level_from_cam
    s = (R[1, 0] * x + R[1, 1] * y + R[1, 2]) / np.sqrt(x * x + y * y + 1.0)  # sin(depression)
    return np.clip(1.0 - s / np.sin(np.radians(far_deg)), 0.0, 1.0)


def rewards(F: np.ndarray, valid: np.ndarray, weights: np.ndarray) -> np.ndarray:
    """(T, W + 1) cumulative reward ``weights . F`` per column of the image width, with
    columns where a track is invalid forbidden."""
    W = F.shape[2] - 1
    w = np.asarray(weights, float)
    A = ties.dot(w[:, None, None], F, axis=0) / W   # not BLAS: the same bits on every CPU
    bad = np.zeros(A.shape)
    bad[:, 1:] = np.cumsum(~valid, axis=1)
    return A - FORBIDDEN * bad


def events(coef: np.ndarray, rows: np.ndarray, valid: np.ndarray, verticals: np.ndarray,
           camera: Camera, p: SearchParams) -> Events:
    """All corners, border crossings and occluding steps of N lines (TOP = N, BOTTOM = N + 1).

    Args:
        coef: (N, 3) candidate floor lines.
        rows: (N + 2, W) track rows; valid: (N + 2, W) per-column validity.
        verticals: (V, 4) segments of 3D-vertical lines ``[u1, v1, u2, v2]``.
    """
    W = camera.width
    n = len(coef)
    top = n
    src, dst, us, step = [], [], [], []
    # corners: both orders (which line is on the left)
    X = np.cross(coef[:, None, :], coef[None, :, :])
    w = X[..., 2]
    ok = np.abs(w) > 1e-9
    ws = np.where(ok, w, 1.0)
    cu, cv = X[..., 0] / ws, X[..., 1] / ws
    ok &= (cu > 0.0) & (cu < W - 1.0) & (np.abs(cv) < 1e6)
    cu, cv = np.where(ok, cu, 0.0), np.where(ok, cv, 0.0)
    ok &= camera.below_horizon(np.column_stack([cu.ravel(), cv.ravel()]),
                               p.horizon_margin).reshape(n, n)
    np.fill_diagonal(ok, False)
    ii, jj = np.nonzero(ok)
    src.append(ii), dst.append(jj), us.append(cu[ii, jj]), step.append(np.zeros(len(ii), bool))
    # crossings of the top border (v = -0.5) into / out of TOP, and of the bottom border
    for track, vb in ((top, -0.5), (top + 1, camera.height - 0.5)):
        with np.errstate(divide="ignore", invalid="ignore"):
            ut = -(coef[:, 1] * vb + coef[:, 2]) / coef[:, 0]
        okt = np.isfinite(ut) & (ut > 0) & (ut < W - 1)
        ut = np.where(okt, ut, 0.0)
        okt &= camera.below_horizon(np.column_stack([ut, np.full(n, vb)]), p.horizon_margin)
        it = np.nonzero(okt)[0]
        for a, b in ((it, np.full(len(it), track)), (np.full(len(it), track), it)):
            src.append(a), dst.append(b), us.append(ut[it]), step.append(np.zeros(len(it), bool))
    # occluding steps at the foot of vertical edges: for each edge in turn, (near, far) for
    # every near line at its foot and farther track, then the same pairs reversed
    seg = np.asarray(verticals, float).reshape(-1, 4)
    lower = seg[:, 1] > seg[:, 3]                 # the foot is the lower end
    fu, fv = np.where(lower, seg[:, 0], seg[:, 2]), np.where(lower, seg[:, 1], seg[:, 3])
    k = np.round(fu)
    ok = ~(np.hypot(seg[:, 2] - seg[:, 0], seg[:, 3] - seg[:, 1]) < p.min_vertical_px)
    ok &= (k >= 1) & (k <= W - 2)
    k, fu, fv = k[ok].astype(int), fu[ok], fv[ok]
    r = rows[:, k]                                                   # (N + 2, V)
    near = valid[:n, k] & (np.abs(r[:n] - fv) <= p.step_foot_tol_px)  # (N, V)
    far = valid[: n + 1, k] & (r[: n + 1] < fv - p.step_min_jump_px)  # (N + 1, V)
    e, a, b = np.nonzero(near.T[:, :, None] & far.T[:, None, :])     # by edge, near, far
    if len(e):
        c = np.bincount(e, minlength=len(k))                          # pairs per edge
        first = np.arange(len(e)) + np.repeat(np.cumsum(c) - c, c)   # 2 blocks per edge
        at = np.concatenate([first, first + np.repeat(c, c)])
        for out, vals in ((src, np.concatenate([a, b])), (dst, np.concatenate([b, a])),
                          (us, np.concatenate([fu[e], fu[e]]))):
            arr = np.empty(2 * len(e), vals.dtype)
            arr[at] = vals
            out.append(arr)
        step.append(np.ones(2 * len(e), bool))
    cat = np.concatenate
    u_all = cat(us) if us else np.zeros(0)
    return Events(cat(src).astype(int), cat(dst).astype(int),
                  np.clip(np.round(u_all + 0.5), 1, W - 1).astype(int), u_all, cat(step))


def best_paths(A: np.ndarray, valid: np.ndarray, ev: Events, corner_cost: float,
               step_cost: float, limit: int = 1 << 30) -> list[tuple[float, int, tuple[int, ...]]]:
    """Best path through every event, and every single track spanning the image.

    Args:
        A: (T, W + 1) cumulative rewards (``rewards``); valid: (T, W).
        corner_cost, step_cost: cost of a corner / crossing and of an occluding step.
        limit: return at most this many paths (the best).

    Returns:
        list of (score, start track, event indices left to right), best first, distinct.
    """
    n_tracks, W1 = A.shape
    W = W1 - 1
    order = np.argsort(ev.col, kind="stable")
    src = ev.src.tolist()
    # per event, in column order: reward tables at its column before / after it, its cost
    Ai, Aj = A[ev.src, ev.col], A[ev.dst, ev.col]
    cost = np.where(ev.step, step_cost, corner_cost)
    seq = list(zip(order.tolist(), ev.src[order].tolist(), ev.dst[order].tolist(),
                   Ai[order].tolist(), Aj[order].tolist(), cost[order].tolist()))
    # forward: potential F[t] so that the best prefix value on t at column k is F[t] + A[t][k]
    F = np.where(valid[:, 0], -A[:, 0], NEG).tolist()
    ptr = [-1] * n_tracks
    fval, pred = [NEG] * len(src), [-1] * len(src)
    for e, i, j, ai, aj, c in seq:
        fi = F[i]
        if fi <= NEG:
            continue
        val = fi + ai - c
        fval[e], pred[e] = val, ptr[i]
        new, old = val - aj, F[j]
        # better by more than TIE_ABS + TIE_REL * max(|new|, |old|), else a tie: the first met
        d = new - old
        if d > TIE_ABS:
            an = new if new >= 0.0 else -new
            ao = old if old >= 0.0 else -old
            if d > TIE_ABS + TIE_REL * (an if an >= ao else ao):   # a tie: the first met
                F[j], ptr[j] = new, e
    # backward: B[t] so that the best suffix value from column k on t is B[t] - A[t][k]
    B = np.where(valid[:, -1], A[:, W], NEG).tolist()
    ptrb = [-1] * n_tracks
    sval, succ = [NEG] * len(src), [-1] * len(src)
    for e, i, j, ai, aj, c in reversed(seq):
        bj = B[j]
        if bj <= NEG:
            continue
        suf = bj - aj
        sval[e], succ[e] = suf, ptrb[j]
        new, old = suf - c + ai, B[i]
        d = new - old   # beats, as above
        if d > TIE_ABS:
            an = new if new >= 0.0 else -new
            ao = old if old >= 0.0 else -old
            if d > TIE_ABS + TIE_REL * (an if an >= ao else ao):
                B[i], ptrb[i] = new, e
    # candidates: single tracks spanning the image, then the best path through each event
    single = np.nonzero(valid[:, 0] & valid[:, -1])[0]
    fv, sv = np.array(fval), np.array(sval)
    through = np.nonzero((fv > NEG) & (sv > NEG))[0]
    total = np.concatenate([A[single, W] - A[single, 0], fv[through] + sv[through]])
    size = np.concatenate([np.maximum(np.abs(A[single, W]), np.abs(A[single, 0])),
                           np.maximum(np.abs(fv[through]), np.abs(sv[through]))])
    which = np.concatenate([-1 - single, through])   # < 0: a single track
    keep = total > -FORBIDDEN / 2
    total, which, size = total[keep], which[keep], size[keep]
    out, seen = [], set()
    # best first; ties (within the rounding of the values they were summed from) in
    # candidate order: single tracks, then events by index
    for c in ties.order(total, rtol=0.0, atol=TIE_ABS + TIE_REL * size).tolist():
        if len(out) >= limit:
            break
        e = int(which[c])
        if e < 0:
            out.append((float(total[c]), -1 - e, ()))
            continue
        chain_ = [e]
        p = pred[e]
        while p >= 0:
            chain_.append(p)
            p = pred[p]
        chain_.reverse()
        q = succ[e]
        while q >= 0:
            chain_.append(q)
            q = succ[q]
        key = tuple(chain_)
        if key not in seen:
            seen.add(key)
            out.append((float(total[c]), src[chain_[0]], key))
    return out
