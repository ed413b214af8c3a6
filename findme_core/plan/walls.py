"""The room's wall lines from every posed photo's wall-base samples: robust lines supported
by many photos, told apart from furniture in front of a wall and from walls of the next room
seen through a door.

Frames and units: (x, z) floor points of the room frame (metres); a line is a unit normal n
(2,) and offset d with n . p = d; its direction is u = (n_z, -n_x) and a point's place along
it is u . p. Angles in radians.

1. Evidence (``evidence``): each placed photo's WALL scan samples in the room frame, with
   their 1-sigma (``layout``), the floor length each stands for, the direction of the wall
   segment it lies on, and the camera it was seen from.
2. Lines (``fit``), sequential and robust: every layout wall segment proposes a line; the
   proposal with the most seen length of samples within ``gate`` sigmas (and of a like
   direction) wins, is refitted by iteratively reweighted total least squares (Tukey,
   weights length / sigma^2), and takes its samples; repeat. Manhattan where the evidence
   says so: when most of the lines' length lies near two perpendicular axes, each line whose
   direction agrees with them within its fit's uncertainty is turned onto them. A line's
   extent is the span of its samples along it.
3. What each line is: ``wall_kinds.classify`` (the room's wall, furniture in front of one,
   another room's wall seen through a door).

Pure numpy; no I/O.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from findme_core.motion import register
from findme_core.single.search import SegKind


@dataclass(frozen=True)
class WallParams:
    """Line search and classification.

    Attributes:
        gate: a sample is on a line within this many of its sigmas ...
        gate_min_m, gate_max_m: ... but never nearer than ``gate_min_m`` nor farther than
            ``gate_max_m``.
        angle_deg: a sample's wall segment within this angle of the line's direction.
        min_seen_m: a line needs at least this seen length of samples.
        min_segment_m: shorter layout walls propose no line.
        max_lines: at most this many lines.
        manhattan_share: the Manhattan test: this share of the lines' seen length agrees
            with two perpendicular axes (``snap_deg``).
        snap_deg: a line is turned onto the axes when its direction agrees with them
            within 3 sigma of its fit or this, whichever is larger (noise-free lines 3 deg
            off stay off).
        beyond_share: a line with this share of its seen length seen through another line
            lies beyond it.
        front_max_m: furniture stands at most this far in front of its wall.
        cover_share: the wall behind covers at least this share of the furniture's extent.
        parallel_deg: lines this close in direction are parallel.
        max_gap_m: samples of one line farther apart along it than this (wider than a
            wide opening) are different walls.
        gap_m: a ray crossing a line counts as seen through it only where the line has no
            sample within this distance (a gap in it: a door or an opening); where the
            line was seen, a ray across it means it is no obstacle (a rug's edge) ...
        strength: ... unless the line is this many times stronger (seen length) than the
            line seen through it (a door's threshold seen as a boundary by some photo).
        min_wall_m: a line seen less than this is "weak": too little to bound the room.
        corner_deg, reach_m, corner_in_m: a line's extent is carried on to the nearest
            crossing line (at least ``corner_deg`` apart) up to ``reach_m`` past its end
            (or pulled back to it from ``corner_in_m`` inside), ``complete``.
    """

    gate: float = 2.5
    gate_min_m: float = 0.05
    gate_max_m: float = 0.25
    angle_deg: float = 12.0
    min_seen_m: float = 0.3
    min_segment_m: float = 0.3
    max_lines: int = 40
    snap_deg: float = 2.0
    manhattan_share: float = 0.7
    beyond_share: float = 0.5
    front_max_m: float = 1.5
    cover_share: float = 0.6
    parallel_deg: float = 6.0
    max_gap_m: float = 3.0
    gap_m: float = 0.15
    strength: float = 2.0
    min_wall_m: float = 0.8
    corner_deg: float = 30.0
    reach_m: float = 3.0
    corner_in_m: float = 0.3


@dataclass(frozen=True)
class Evidence:
    """Wall-base samples of the placed photos in the room frame.

    Attributes:
        points: (S, 2) sample points, metres.
        sigma: (S,) their 1-sigma, metres.
        length: (S,) floor length each sample stands for, metres.
        direction: (S, 2) unit direction of the layout wall the sample lies on.
        photo: (S,) index of the photo that saw it.
        cams: (N, 2) camera positions (NaN for photos not placed).
        segments: (W, 2, 2) the layouts' wall segments; ``segment_photo`` (W,) their photo.
    """

    points: np.ndarray
    sigma: np.ndarray
    length: np.ndarray
    direction: np.ndarray
    photo: np.ndarray
    cams: np.ndarray
    segments: np.ndarray
    segment_photo: np.ndarray


@dataclass(frozen=True)
class WallLines:
    """Lines found in the evidence: normals (K, 2), offsets (K,), extent (K, 2) [lo, hi]
    along each line's direction, seen length (K,) metres, photos (K,) that saw each,
    ``kind`` (K,) one of "wall", "furniture", "beyond", "weak", the sample's line (S,) (-1: none)
    the Manhattan axis (radians in [0, pi/2), or None) and whether each line was turned onto
    it (K,)."""

    normals: np.ndarray
    offsets: np.ndarray
    extent: np.ndarray
    seen_m: np.ndarray
    photos: np.ndarray
    kind: np.ndarray
    sample_line: np.ndarray
    manhattan: float | None
    snapped: np.ndarray | None = None

    @property
    def walls(self) -> np.ndarray:
        """Indices of the lines that are the room's walls."""
        return np.flatnonzero(self.kind == "wall")


def direction(n) -> np.ndarray:
    """Unit direction(s) u = (n_z, -n_x) of line normal(s) n (..., 2)."""
    n = np.asarray(n, float)
    return np.stack([n[..., 1], -n[..., 0]], -1)


def evidence(layouts, poses) -> Evidence:
    """The WALL samples of N photos' layouts (None: no layout) at poses (N, 3) (NaN rows: not
    placed), in the room frame."""
    poses = np.asarray(poses, float).reshape(-1, 3)
    P, S, Ln, Dr, Ph, segs, sph = [], [], [], [], [], [], []
    for i, (L, p) in enumerate(zip(layouts, poses)):
        if L is None or not np.isfinite(p[0]):
            continue
        yaw = np.array([p[2]])
        if len(L.walls):
            w = register.rot2(yaw, L.walls.reshape(-1, 2))[0].reshape(-1, 2, 2) + p[:2]
            segs.append(w)
            sph.append(np.full(len(w), i))
        m = np.flatnonzero((L.kind == SegKind.WALL) & np.isfinite(L.range) & (L.wall >= 0))
        if not len(m):
            continue
        q = L.points[m]
        gap = np.linalg.norm(np.diff(q, axis=0), axis=1)
        same = np.diff(L.wall[m]) == 0
        g = np.where(same, np.minimum(gap, 0.3), 0.0)
        length = 0.5 * (np.r_[0.0, g] + np.r_[g, 0.0])
        d = L.walls[L.wall[m], 1] - L.walls[L.wall[m], 0]
        d /= np.maximum(np.linalg.norm(d, axis=1, keepdims=True), 1e-12)
        P.append(register.rot2(yaw, q)[0] + p[:2])
        Dr.append(register.rot2(yaw, d)[0])
        S.append(L.sigma[m])
        Ln.append(length)
        Ph.append(np.full(len(m), i))
    cat = (lambda xs, shape: np.concatenate(xs) if xs else np.zeros(shape))
    return Evidence(cat(P, (0, 2)), cat(S, 0), cat(Ln, 0), cat(Dr, (0, 2)),
                    cat(Ph, 0).astype(int), poses[:, :2].copy(), cat(segs, (0, 2, 2)),
                    cat(sph, 0).astype(int))


def _snap(n, axis, tol):
    """n turned onto the nearest axis direction when within tol (radians)."""
    a = np.arctan2(n[1], n[0])
    q = axis + np.round((a - axis) / (np.pi / 2)) * (np.pi / 2)
    if abs(np.angle(np.exp(1j * (a - q)))) <= tol:
        return np.array([np.cos(q), np.sin(q)]), True
    return n, False


def _inliers(ev: Evidence, n, d, free, params: WallParams):
    r = ev.points @ n - d
    gate = np.clip(params.gate * ev.sigma, params.gate_min_m, params.gate_max_m)
    like = np.abs(ev.direction @ n) < np.sin(np.radians(params.angle_deg))
    return free & like & (np.abs(r) < gate), r, gate


def _refit(ev: Evidence, n, d, free, fixed_dir: bool, params: WallParams):
    """IRLS (Tukey, 1/sigma^2) of a line on its inliers; the direction kept when fixed."""
    for _ in range(4):
        inl, r, gate = _inliers(ev, n, d, free, params)
        if inl.sum() < 2:
            return n, d, inl
        w = (1.0 - (r[inl] / gate[inl]) ** 2) ** 2 * ev.length[inl] / ev.sigma[inl] ** 2
        p = ev.points[inl]
        c = (w[:, None] * p).sum(0) / w.sum()
        if not fixed_dir:
            X = (p - c) * np.sqrt(w)[:, None]
            n_new = np.linalg.svd(X, full_matrices=False)[2][-1]
            n = n_new if n_new @ n > 0 else -n_new
        d = float(n @ c)
    return n, d, _inliers(ev, n, d, free, params)[0]


def _main_run(ev: Evidence, n, inl, max_gap: float) -> np.ndarray:
    """The inliers of the run along the line (no gap wider than ``max_gap``) with the most
    seen length: collinear walls far apart are different walls."""
    idx = np.flatnonzero(inl)
    if len(idx) < 2:
        return inl
    t = ev.points[idx] @ direction(n)
    o = np.argsort(t)
    run = np.r_[0, np.cumsum(np.diff(t[o]) > max_gap)]
    best = np.argmax(np.bincount(run, weights=ev.length[idx][o]))
    out = np.zeros_like(inl)
    out[idx[o][run == best]] = True
    return out


def fit(ev: Evidence, params: WallParams = WallParams()) -> WallLines:
    """Lines of the evidence, strongest first (see the module docstring), unclassified
    (every ``kind`` "wall"; ``classify`` tells them apart)."""
    segs = ev.segments
    sl = np.hypot(*(segs[:, 1] - segs[:, 0]).T) if len(segs) else np.zeros(0)
    props = []
    for s in np.flatnonzero(sl >= params.min_segment_m):
        u = (segs[s, 1] - segs[s, 0]) / sl[s]
        n = np.array([-u[1], u[0]])
        props.append((n, float(n @ segs[s].mean(0))))
    free = np.ones(len(ev.points), bool)
    sample_line = np.full(len(ev.points), -1)
    N, D = [], []
    while len(N) < params.max_lines and props and free.any():
        sup = [float(ev.length[_inliers(ev, n, d, free, params)[0]].sum()) for n, d in props]
        b = int(np.argmax(sup))
        if sup[b] < params.min_seen_m:
            break
        n, d, inl = _refit(ev, *props.pop(b), free, False, params)
        inl = _main_run(ev, n, inl, params.max_gap_m)
        if ev.length[inl].sum() < params.min_seen_m:
            continue
        sample_line[inl] = len(N)
        free &= ~inl
        N.append(n)
        D.append(d)
    K = len(N)
    N, D = np.array(N).reshape(K, 2), np.array(D, float)
    seen = np.bincount(sample_line[sample_line >= 0], weights=ev.length[sample_line >= 0],
                       minlength=K)
    axis, snapped = _manhattan(ev, N, D, sample_line, seen, params)
    E = np.zeros((K, 2))
    photos = np.zeros(K, int)
    for k in range(K):
        m = sample_line == k
        t = ev.points[m] @ direction(N[k])
        E[k] = t.min(), t.max()
        photos[k] = len(np.unique(ev.photo[m]))
    return WallLines(N, D, E, seen, photos, np.full(K, "wall", object), sample_line, axis,
                     snapped)


def _manhattan(ev: Evidence, N, D, sample_line, seen, params: WallParams):
    """The room's axis from the lines and each line turned onto it (N, D changed in place)
    when its direction agrees with the axis within max(3 sigma of its fit, ``snap_deg``);
    no axis unless ``manhattan_share`` of the seen length agrees."""
    K = len(N)
    snapped = np.zeros(K, bool)
    if K < 2 or seen.sum() <= 0:
        return None, snapped
    ang = np.arctan2(N[:, 1], N[:, 0])
    tol = np.zeros(K)
    for k in range(K):   # how far each line's direction may be from an axis: its fit's 3 sigma
        m = sample_line == k
        p, w = ev.points[m], ev.length[m] / ev.sigma[m] ** 2
        t, r = p @ direction(N[k]), p @ N[k] - D[k]
        tc = t - (w * t).sum() / w.sum()
        n_eff = w.sum() ** 2 / max((w * w).sum(), 1e-300)
        sig = np.sqrt((w * r * r).sum() / max((w * tc * tc).sum(), 1e-12) / max(n_eff - 2, 1.0))
        tol[k] = max(3.0 * sig, np.radians(params.snap_deg))

    def on_axes(a):
        return np.abs(np.angle(np.exp(4j * (ang - a)))) / 4.0 <= tol
    # the axis that the most seen length agrees with (each line's own direction a candidate)
    axis = max(ang % (np.pi / 2), key=lambda a: seen[on_axes(a)].sum())
    for _ in range(2):
        s = on_axes(axis)
        axis = float(np.angle(np.sum(seen[s] * np.exp(4j * ang[s]))) / 4.0) % (np.pi / 2)
    s = on_axes(axis)
    if seen[s].sum() < params.manhattan_share * seen.sum():
        return None, snapped
    for k in np.flatnonzero(s):
        m = sample_line == k
        p, w = ev.points[m], ev.length[m] / ev.sigma[m] ** 2
        N[k] = _snap(N[k], axis, np.pi)[0]
        D[k] = float((w * (p @ N[k])).sum() / w.sum())
        snapped[k] = True
    return axis, snapped
