"""How two photos' layouts (``layout``) agree under a planar motion, and the motions that
wall and corner correspondences imply: the layout part of the registration of two photos
(``estimator``; also used to fuse a session's photos into a floor plan, ``fuse``).

Convention (DESIGN.md): the motion of (A, B) is the pose of camera B in A's level frame; a
floor point p_B = (x, z) of B is p_A = R(yaw) p_B + t in A, R(yaw) = [[c, s], [-s, c]] on
(x, z) (the x-z block of R_y), t = (x, z) metres, yaw radians (> 0: B turned right of A).

Agreement of a motion: each WALL sample of one photo's scan is moved into the other photo
and looked up in its scan at the same azimuth. Within ``gate`` sigmas of a WALL sample there
(the same wall base seen by both) it agrees (MSAC weight, times ``weight``); nearer than the
other photo's boundary by more than the gate (on floor the other photo sees, where no wall
can stand) it is a violation (``violation``); farther (hidden behind the other photo's
walls) or outside its view it says nothing. Both ways (B into A and A into B).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from findme_core.errors import MotionError
from findme_core.geometry import ties
from findme_core.single.layout import KIND_WALL, KIND_OPEN, Layout


@dataclass(frozen=True)
class RegisterParams:
    """Gates and weights of the layout terms.

    Attributes:
        gate: a sample agrees within this many sigmas (its and the other photo's combined).
        weight: score of one fully agreeing sample (one feature inlier scores 1).
        violation: score lost per sample lying on floor the other photo sees.
        parallel_deg: walls this close in direction may be one wall.
        min_angle_deg: two walls fix a translation when at least this far from parallel.
        min_wall_m: shorter walls give no yaw candidate.
        sigma_ref: samples with a larger sigma (metres) count less (their weight falls as
            (sigma_ref / sigma)^2).
        outside: score lost when a camera lies beyond the other photo's walls.
        max_walls: at most this many walls (the longest) and corners of each photo propose
            translations.
    """

    gate: float = 3.0
    weight: float = 0.25
    violation: float = 0.25
    parallel_deg: float = 6.0
    min_angle_deg: float = 30.0
    min_wall_m: float = 0.4
    sigma_ref: float = 0.1
    outside: float = 10.0
    max_walls: int = 8


@dataclass(frozen=True)
class Agreement:
    """What the layouts say about one motion.

    Attributes:
        rank_a, rank_b: hypothesis ranks of the two layouts (1 = best).
        samples: boundary samples (both photos) on a wall of the other photo within the gate.
        violations: boundary samples on floor the other photo sees.
        rms_m: rms distance of the agreeing samples to the other photo's wall, metres.
        walls: (wall of A, wall of B) pairs that at least 3 samples put on each other.
        corners: (corner of A, corner of B) pairs within the gate of each other.
        score: the layout part of the motion's score.
    """

    rank_a: int
    rank_b: int
    samples: int
    violations: int
    rms_m: float
    walls: tuple
    corners: tuple
    score: float

    def check_fixes_translation(self, la: Layout) -> None:
        """Without feature matches, the walls must fix both directions of the translation:
        a corner in common, or walls of A (``la``, the layout it was scored with) at least
        30 deg apart. Raises MotionError naming what the photos share otherwise."""
        if self.corners:
            return
        n = la.normals[[i for i, _ in self.walls]] if self.walls else np.zeros((0, 2))
        cross = n[:, None, 0] * n[None, :, 1] - n[:, None, 1] * n[None, :, 0]
        if len(n) and np.abs(cross).max() > np.sin(np.radians(30)):
            return
        what = "one wall" if len({i for i, _ in self.walls}) <= 1 else "only parallel walls"
        raise MotionError(f"the photos share {what} and no feature match agrees: the motion "
                          "along the wall cannot be measured")


def rot2(yaw, p) -> np.ndarray:
    """R(yaw) p for C yaws (C,) and points (S, 2) or (C, S, 2): (C, S, 2)."""
    x, z = _turned(yaw, p[..., 0], p[..., 1])
    out = np.empty(x.shape + (2,))   # filled, not stacked
    out[..., 0], out[..., 1] = x, z
    return out


def _turned(yaw, x, z):
    """``rot2`` by components: R(yaw) (x, z) for C yaws (C,) and coordinates x, z that
    broadcast against (C, 1); returns (x, z), (C, S) each."""
    c, s = np.cos(yaw)[:, None], np.sin(yaw)[:, None]
    return c * x + s * z, -s * x + c * z


def _lookup(L: Layout, az: np.ndarray):
    """Index of the nearest scan sample of L at each azimuth, and whether one is near (within
    1.5 sample spacings)."""
    if len(L.azimuth) < 2:
        return np.zeros(az.shape, int), np.zeros(az.shape, bool)
    return L.scan.nearest(az)


def _one_way(dst: Layout, src: Layout, yaw, t, into_a: bool, gate: float):
    """src's WALL samples moved into dst for C motions. Returns (normalised residual e
    (C, S), agrees (C, S), violates (C, S), dst sample index (C, S), src sample index (S,),
    combined sigma (C, S), metres)."""
    k = np.flatnonzero(src.kind == KIND_WALL)
    px, pz = src.points[k, 0], src.points[k, 1]
    if into_a:   # R(yaw) p + t, by components
        qx, qz = _turned(yaw, px, pz)
        qx += t[:, 0, None]
        qz += t[:, 1, None]
    else:        # R(-yaw) (p - t)
        qx, qz = _turned(-yaw, px - t[:, 0, None], pz - t[:, 1, None])
    az, rho = np.arctan2(qx, qz), np.hypot(qx, qz)
    j, near = _lookup(dst, az)
    kind = dst.kind[j]
    sig = np.hypot(dst.sigma[j], src.sigma[k])
    e = (rho - dst.range[j]) / sig
    agree = near & (kind == KIND_WALL) & (np.abs(e) < gate)
    bound = (kind == KIND_WALL) | (kind == KIND_OPEN)
    return e, agree, near & bound & (e < -gate), j, k, sig


def _camera_outside(dst: Layout, yaw, t, into_a: bool, gate: float) -> np.ndarray:
    """(C,) whether the other camera (B's centre t in A, or A's centre in B) lies beyond
    dst's boundary in dst's view: outside the room dst sees."""
    c = t if into_a else rot2(-yaw, -t[:, None])[:, 0]
    az, rho = np.arctan2(c[:, 0], c[:, 1]), np.hypot(c[:, 0], c[:, 1])
    j, near = _lookup(dst, az)
    wall = dst.kind[j] == KIND_WALL
    return near & wall & (rho > dst.range[j] + gate * dst.sigma[j])


def scores(la: Layout, lb: Layout, yaw, t, p: RegisterParams = RegisterParams()) -> np.ndarray:
    """(C,) layout score of C motions (yaw (C,), t (C, 2)): agreeing samples (MSAC, each
    weighted by min(1, (sigma_ref / sigma)^2): a far, uncertain wall says little) minus
    violations, both ways, minus ``outside`` when a camera lies outside the other's room."""
    yaw, t = np.atleast_1d(yaw), np.atleast_2d(t)
    total = np.zeros(len(yaw))
    for dst, src, into_a in ((la, lb, True), (lb, la, False)):
        e, agree, viol, _, _, sig = _one_way(dst, src, yaw, t, into_a, p.gate)
        w = np.minimum(1.0, (p.sigma_ref / sig) ** 2)
        total += p.weight * np.sum(np.where(agree, (1.0 - (e / p.gate) ** 2) * w, 0.0), 1) \
            - p.violation * viol.sum(1) \
            - p.outside * _camera_outside(dst, yaw, t, into_a, p.gate)
    return total


def agreement(la: Layout, lb: Layout, yaw: float, t, p: RegisterParams = RegisterParams()
              ) -> Agreement:
    """The evidence of the layouts for one motion (see ``Agreement``)."""
    t = np.asarray(t, float).reshape(1, 2)
    n_agree, n_viol, dist, pairs = 0, 0, [], {}
    for dst, src, into_a in ((la, lb, True), (lb, la, False)):
        ks, w, q, _ = _associate(dst, src, yaw, t, into_a, p.gate)
        n_viol += int(_one_way(dst, src, np.array([yaw]), t, into_a, p.gate)[2].sum())
        n_agree += len(ks)
        n, c, _ = _lines(dst)
        dist.append(np.einsum("sj,sj->s", q, n[w]) - c[w] if len(ks) else np.zeros(0))
        for wd, ws in zip(w, src.wall[ks]):
            key = (int(wd), int(ws)) if into_a else (int(ws), int(wd))
            pairs[key] = pairs.get(key, 0) + 1
    dist = np.concatenate(dist)
    ca, cb = la.corners, lb.corners
    corners = ()
    if len(ca) and len(cb):
        d = np.linalg.norm(ca[:, None] - (rot2(np.array([yaw]), cb)[0] + t)[None], axis=2)
        corners = tuple((int(i), int(j)) for i, j in zip(*np.nonzero(d < 0.15 + 0.05 * np.hypot(
            *ca.T)[:, None])))
    return Agreement(la.rank, lb.rank, n_agree, n_viol,
                     float(np.sqrt(np.mean(dist ** 2))) if len(dist) else float("nan"),
                     tuple(sorted(k for k, v in pairs.items() if v >= 3 and k[1] >= 0)), corners,
                     float(scores(la, lb, np.array([yaw]), t, p)[0]))


# ---------------------------------------------------------------------------- candidates
def _lines(L: Layout):
    """Unit normals (K, 2) toward the camera, offsets n . p (K,) (< 0) and lengths (K,)."""
    n = L.normals
    return n, np.einsum("ij,ij->i", n, L.walls[:, 0]), np.linalg.norm(
        L.walls[:, 1] - L.walls[:, 0], axis=1)


def _longest(n, c, length, k: int):
    """The k longest walls' (normals, offsets): candidate generation stays bounded."""
    o = ties.order(length)[:k]   # walls of one length (a symmetric room): in index order
    return n[o], c[o]


def wall_yaws(la: Layout, lb: Layout, p: RegisterParams = RegisterParams()) -> np.ndarray:
    """Yaws that put a wall of B on a wall of A with the cameras on the same side (the
    normals toward each camera agree): azimuth of A's normal minus azimuth of B's; the
    longest pairs (product of the lengths) first."""
    (na, _, sa), (nb, _, sb) = _lines(la), _lines(lb)
    ka, kb = sa >= p.min_wall_m, sb >= p.min_wall_m
    na, nb, sa, sb = na[ka], nb[kb], sa[ka], sb[kb]
    az_a, az_b = np.arctan2(na[:, 0], na[:, 1]), np.arctan2(nb[:, 0], nb[:, 1])
    yaw = np.angle(np.exp(1j * (az_a[:, None] - az_b[None]))).ravel()
    return yaw[ties.order(np.outer(sa, sb).ravel())]   # equal products: in index order


def translations(la: Layout, lb: Layout, yaw: float, directions=None,
                 p: RegisterParams = RegisterParams(), single: bool = False) -> np.ndarray:
    """(N, 2) translations t that, at this yaw, put two non-parallel walls of B on two of A,
    a corner of B on a corner of A, or (given unit ``directions`` (D, 2) of the baseline,
    e.g. from the features) one wall of B on one of A along a direction; with ``single``,
    also one wall on one wall by the shortest move (the position along the wall is then
    unknown: a degenerate pair, which the caller reports). ``Translations`` for many yaws."""
    return Translations(la, lb, p)(yaw, directions, single)


class Translations:
    """``translations`` of one layout pair at a few yaws: each photo's longest walls and
    corners taken once, and per yaw the same-wall pairs and the translations that need no
    direction kept (calls with and without directions share them); the same arithmetic,
    the same numbers. ``Translations(la, lb, p)(yaw, directions, single)``."""

    def __init__(self, la: Layout, lb: Layout, p: RegisterParams = RegisterParams()):
        self.walls = [_longest(*_lines(L), p.max_walls) for L in (la, lb)]
        self.corners = la.corners[:p.max_walls], lb.corners[:p.max_walls]
        self.p, self.memo = p, {}

    def _at(self, yaw: float):
        """(normals n (P, 2) and offsets c_A - c_B (P,) of the same-wall pairs, or None
        without walls in both; two-wall translations (N, 2); corner translations (Q, 2))."""
        key = float(yaw)
        if key not in self.memo:
            (na, ca), (nb, cb) = self.walls
            qa, qb = self.corners
            pairs, two, corner = None, np.zeros((0, 2)), np.zeros((0, 2))
            if len(na) and len(nb):
                nbr = rot2(np.array([key]), nb)[0]
                ia, ib = np.nonzero(na @ nbr.T > np.cos(np.radians(self.p.parallel_deg)))
                n, rhs = na[ia], ca[ia] - cb[ib]            # n . t = c_A - c_B (same wall)
                i, j = np.triu_indices(len(n), 1)
                det = n[i, 0] * n[j, 1] - n[i, 1] * n[j, 0]
                ok = np.abs(det) > np.sin(np.radians(self.p.min_angle_deg))
                i, j, det = i[ok], j[ok], det[ok]
                pairs = (n, rhs)
                two = np.column_stack([(rhs[i] * n[j, 1] - rhs[j] * n[i, 1]) / det,
                                       (n[i, 0] * rhs[j] - n[j, 0] * rhs[i]) / det])
            if len(qa) and len(qb):
                corner = (qa[:, None] - rot2(np.array([key]), qb)[0][None]).reshape(-1, 2)
            self.memo[key] = pairs, two, corner
        return self.memo[key]

    def __call__(self, yaw: float, directions=None, single: bool = False) -> np.ndarray:
        pairs, two, corner = self._at(yaw)
        out = [np.zeros((0, 2)), two]
        if pairs is not None:
            n, rhs = pairs
            if single:
                out.append(rhs[:, None] * n)
            if directions is not None and len(directions):
                d = np.asarray(directions, float).reshape(-1, 2)
                nd = n @ d.T                                   # (P, D)
                with np.errstate(divide="ignore", invalid="ignore"):
                    s = rhs[:, None] / nd
                ok = (np.abs(nd) > 0.3) & (s > 0)
                out.append(s[ok][:, None] * d[np.nonzero(ok)[1]])
        out.append(corner)
        return np.vstack(out)


def _associate(dst: Layout, src: Layout, yaw: float, t, into_a: bool, gate: float):
    """src's samples that agree with dst under one motion, each with the dst wall nearest to
    it (point to segment): (src sample indices (S,), dst wall indices (S,), moved points
    (S, 2), combined sigma (S,))."""
    _, agree, _, _, k, sig = _one_way(dst, src, np.array([yaw]), t, into_a, gate)
    a = agree[0]
    if not a.any() or len(dst.walls) == 0:
        return np.zeros(0, int), np.zeros(0, int), np.zeros((0, 2)), np.zeros(0)
    p = src.points[k[a]]
    q = (rot2(np.array([yaw]), p)[0] + t[0]) if into_a else rot2(np.array([-yaw]), p - t[0])[0]
    w0, d = dst.walls[:, 0], dst.walls[:, 1] - dst.walls[:, 0]
    u = np.clip(np.einsum("skj,kj->sk", q[:, None] - w0[None], d)
                / np.maximum(np.einsum("kj,kj->k", d, d), 1e-12), 0.0, 1.0)
    dist = np.linalg.norm(q[:, None] - (w0[None] + u[..., None] * d[None]), axis=2)
    # a sample nearest a corner is as near to both walls: the first wall, on every machine
    return k[a], ties.argmin(dist, axis=1), q, sig[0][a]


def residual_terms(la: Layout, lb: Layout, yaw: float, t, p: RegisterParams = RegisterParams()):
    """The agreeing samples of one motion, frozen for refinement: a function mapping C motions
    (yaw (C,), t (C, 2)) to (C, R) signed distances of each sample to the line of the wall
    nearest to it in the other photo, over its sigma; the samples along one wall share its
    error (the boundary line's), so each wall's count as 2 independent ones."""
    t = np.asarray(t, float).reshape(1, 2)
    terms = []
    for dst, src, into_a in ((la, lb, True), (lb, la, False)):
        ks, w, _, sig = _associate(dst, src, yaw, t, into_a, p.gate)
        if len(ks) == 0:
            continue
        n, c, _ = _lines(dst)
        terms.append((into_a, src.points[ks], n[w], c[w],
                      sig * 1.0))

    def resid(yaw_c, t_c):
        out = [np.zeros((len(yaw_c), 0))]
        for into_a, pts, n, c, sig in terms:
            q = rot2(yaw_c, pts) + t_c[:, None] if into_a else rot2(-yaw_c, pts[None] - t_c[:, None])
            out.append((np.einsum("csj,sj->cs", q, n) - c) / sig)
        return np.concatenate(out, 1)
    return resid
