"""The joint refinement's least-squares problem (``adjust.refine``): which unknowns, which
residuals, and which residual depends on which unknown.

Frames and units: the room frame (x, z metres; level frame of photo 0, which stays at
(0, 0, 0): it fixes the gauge). A photo's pose (x, z, yaw) maps a floor point p of its level
frame to R(yaw) p + (x, z) (``register.rot2``); photos of one spot share (x, z). A wall line
is n . p = d, n = (cos phi, sin phi); lines on the room's axes share one axis angle (phi =
axis + k pi/2), the others have their own.

Unknowns: the position of every spot but photo 0's, the yaw of every photo but photo 0,
per outline line its offset (and angle when off the axes, or the axis angle once), and the
gravity tilt (about level x and z) of every photo in the matches whose gravity is not exact.
Residuals, each in its own 1-sigma: spot position about the placement's (``prior_m``);
sample (n . (R p + c) - d) / sigma_sample; corner (R q + c - vertex) / sigma_sample; turn
(yaw_j - yaw_i - link) / sigma_link; match (angle of the match from its epipolar plane,
``planar.epipolar_residuals``, the bearings turned by their photos' tilts) / (``match_px``
/ f), with the baseline held as placed: the scale-free planes fix the turn between spots,
and along a corridor, where the walls fix no position, they would slide the spots; tilt /
its gravity's 1-sigma.

Pure numpy + scipy.sparse; no I/O.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.sparse import coo_matrix

from findme_core.geometry import planar
from findme_core.motion import register
from findme_core.single.layout import End
from findme_core.single.search import SegKind


@dataclass(frozen=True)
class RefineParams:
    """Association gates, noise and loss.

    Attributes:
        gate: a sample belongs to a wall within this many of its sigmas (clipped to
            ``gate_min_m`` .. ``gate_max_m``), within ``angle_deg`` of its direction and
            inside the wall's span (widened by ``span_m``).
        corner_m: a layout corner within this of an outline vertex is that corner.
        match_px: 1-sigma of a feature's position, pixels.
        match_gate: matches farther than this many sigmas from their epipolar plane at the
            starting poses are left out; at most ``max_matches`` per pair.
        match_eff: a pair's matches weigh together as this many independent ones (they
            share the pair's model errors: gravity, a planar floor, the camera heights);
            counted one by one, hundreds of them slide spots along a corridor, where the
            scale-free epipolar planes are the only term that moves.
        f_scale: the loss turns linear past this many sigmas.
        prior_m: 1-sigma of a spot's position about where the placement put it (the
            placement weighed the free floor, which these residuals do not see: along a
            corridor the walls fix nothing, and scale-free epipolar planes cannot either).
        height_rel: relative 1-sigma of the camera height (scales every length).
    """

    gate: float = 3.0
    gate_min_m: float = 0.05
    gate_max_m: float = 0.25
    angle_deg: float = 12.0
    span_m: float = 0.2
    corner_m: float = 0.3
    match_px: float = 1.5
    match_gate: float = 3.0
    max_matches: int = 200
    match_eff: float = 5.0
    f_scale: float = 1.5
    prior_m: float = 0.3
    height_rel: float = 0.02
    max_nfev: int = 60



def _normal(phi):
    return np.array([np.cos(phi), np.sin(phi)])


def vertices_of(normals, offsets, line, fallback) -> np.ndarray:
    """(V, 2) vertex k = crossing of the lines of edges k - 1 and k (``fallback`` (V, 2)
    where an edge has no line or the two are parallel)."""
    V = len(line)
    out = np.array(fallback, float).copy()
    for k in range(V):
        a, b = line[k - 1], line[k]
        if a < 0 or b < 0 or a == b:
            continue
        A = np.array([normals[a], normals[b]])
        if abs(np.linalg.det(A)) > 1e-6:
            out[k] = np.linalg.solve(A, [offsets[a], offsets[b]])
    return out



class Problem:
    """Parameter layout and residuals (see the module docstring)."""

    def __init__(self, layouts, poses, spot, outline, axis, snapped, links, matches, cams,
                 p: RefineParams, tilt=None):
        self.p = p
        self.N = len(poses)
        placed = np.isfinite(poses[:, 0])
        self.placed = placed
        self.spot = np.asarray(spot)
        s0 = self.spot[0]
        spots = [s for s in np.unique(self.spot[placed]) if s != s0]
        self.spot_ix = {s: 2 * i for i, s in enumerate(spots)}
        self.yaw_ix = {i: 2 * len(spots) + j
                       for j, i in enumerate(k for k in np.flatnonzero(placed) if k != 0)}
        n0 = 2 * len(spots) + len(self.yaw_ix)
        self.line, self.V0 = outline.line, outline.vertices
        lines = outline.lines
        used = sorted(set(int(k) for k in outline.line if k >= 0))
        self.K = len(lines.normals)
        self.axis = axis if axis is not None and any(snapped[k] for k in used) else None
        self.quarter, self.line_ix = {}, {}
        x = [poses[(self.spot == s) & placed][0, :2] for s in spots]   # a placed photo's
        x = list(np.concatenate(x)) if x else []
        x += [poses[i, 2] for i in self.yaw_ix]
        if self.axis is not None:
            self.axis_ix = len(x)
            x.append(self.axis)
        for k in used:
            phi = np.arctan2(lines.normals[k, 1], lines.normals[k, 0])
            if self.axis is not None and snapped[k]:
                self.quarter[k] = phi - self.axis
                self.line_ix[k] = (None, len(x))
                x.append(lines.offsets[k])
            else:
                self.line_ix[k] = (len(x), len(x) + 1)
                x += [phi, lines.offsets[k]]
        self.x0 = np.array(x, float)
        self.prior0 = self.x0[:2 * len(spots)].copy()
        self.n_pose = n0
        self.lines0 = lines
        self._samples(layouts, poses)
        self._links = [(lk.i, lk.j, lk.yaw, lk.sigma) for lk in links
                       if placed[lk.i] and placed[lk.j] and self.spot[lk.i] == self.spot[lk.j]]
        self._matches(matches or {}, poses, cams)
        self._tilts(tilt)

    # ------------------------------------------------------------------ structure
    def _pose_cols(self, i) -> list:
        s = self.spot[i]
        cols = [] if s == self.spot[0] else [self.spot_ix[s], self.spot_ix[s] + 1]
        return cols + ([] if i == 0 else [self.yaw_ix[i]])

    def _line_cols(self, k) -> list:
        if k < 0 or k not in self.line_ix:
            return []
        ia, io = self.line_ix[k]
        return [self.axis_ix if ia is None else ia, io]

    def sparsity(self):
        """(R, P) which parameters each residual depends on, in the order of ``residuals``:
        finite differences then perturb every parameter group that shares no residual at
        once (``least_squares(jac_sparsity=...)``), a few groups instead of P columns."""
        rows = []
        for i, k in zip(self.si, self.sl):
            rows.append(self._pose_cols(i) + self._line_cols(k))
        V = len(self.line)
        for i, _, v, _ in self.corners:
            cols = self._pose_cols(i) + self._line_cols(self.line[v]) + \
                self._line_cols(self.line[(v - 1) % V])
            rows += [cols, cols]
        for i, j, _, _ in self._links:
            rows.append(self._pose_cols(i)[-1:] + self._pose_cols(j)[-1:])
        rows += [[c] for c in range(len(self.prior0))]
        for i, j, a, _, _, _ in self.mt:
            cols = [self.yaw_ix[k] for k in (i, j) if k != 0]
            cols += [c for k in (i, j) if k in self.tilt_ix for c in self.tilt_ix[k]]
            rows += [cols] * len(a)
        rows += [[c] for k in self.tilt_ix for c in self.tilt_ix[k]]
        r = np.repeat(np.arange(len(rows)), [len(c) for c in rows])
        c = np.fromiter((k for cols in rows for k in cols), int, len(r))
        S = coo_matrix((np.ones(len(r), np.int8), (r, c)), shape=(len(rows), len(self.x0)))
        S = S.tocsr()
        S.data[:] = 1          # a column named twice in a row (a corner's two lines) is one
        return S

    # ------------------------------------------------------------------ unpacking
    def pose(self, x, i):
        c = np.zeros(2) if self.spot[i] == self.spot[0] else \
            x[self.spot_ix[self.spot[i]]:self.spot_ix[self.spot[i]] + 2]
        yaw = 0.0 if i == 0 else x[self.yaw_ix[i]]
        return c, yaw

    def lines(self, x):
        n = np.array(self.lines0.normals, float).copy()
        d = np.array(self.lines0.offsets, float).copy()
        for k, (ia, io) in self.line_ix.items():
            phi = x[ia] if ia is not None else x[self.axis_ix] + self.quarter[k]
            n[k], d[k] = _normal(phi), x[io]
        return n, d

    def poses(self, x):
        out = np.full((self.N, 3), np.nan)
        for i in np.flatnonzero(self.placed):
            c, y = self.pose(x, i)
            out[i] = (c[0], c[1], y)
        return out

    # ------------------------------------------------------------------ data
    def _samples(self, layouts, poses):
        V = self.V0
        P, S, I, E, C = [], [], [], [], []
        cos_a = np.cos(np.radians(self.p.angle_deg))
        for i in np.flatnonzero(self.placed):
            L = layouts[i]
            if L is None:
                continue
            m = np.flatnonzero((L.kind == SegKind.WALL) & np.isfinite(L.range) & (L.wall >= 0))
            if len(m) == 0:
                continue
            q = register.rot2(np.array([poses[i, 2]]), L.points[m])[0] + poses[i, :2]
            d = L.walls[L.wall[m], 1] - L.walls[L.wall[m], 0]
            d = register.rot2(np.array([poses[i, 2]]), d)[0]
            d /= np.maximum(np.linalg.norm(d, axis=1, keepdims=True), 1e-12)
            gate = np.clip(self.p.gate * L.sigma[m], self.p.gate_min_m, self.p.gate_max_m)
            best, best_r = np.full(len(m), -1), np.full(len(m), np.inf)
            for k in range(len(V)):
                ln = self.line[k]
                if ln < 0:
                    continue
                a, b = V[k], V[(k + 1) % len(V)]
                u = (b - a) / max(np.linalg.norm(b - a), 1e-12)
                t = (q - a) @ u
                r = np.abs(q @ self.lines0.normals[ln] - self.lines0.offsets[ln])
                ok = (r < gate) & (np.abs(d @ u) > cos_a) & (t > -self.p.span_m) \
                    & (t < np.linalg.norm(b - a) + self.p.span_m) & (r < best_r)
                best[ok], best_r[ok] = ln, r[ok]
            k = best >= 0
            P.append(L.points[m][k])
            S.append(L.sigma[m][k])
            I.append(np.full(int(k.sum()), i))
            E.append(best[k])
            # corners: a wall's right end where the next wall meets it
            cq = L.walls[L.ends[:, 1] == End.CORNER, 1]
            for c in cq:
                w = register.rot2(np.array([poses[i, 2]]), c[None])[0, 0] + poses[i, :2]
                dist = np.linalg.norm(V - w, axis=1)
                v = int(np.argmin(dist))
                if dist[v] < self.p.corner_m and self.line[v] >= 0 and self.line[v - 1] >= 0:
                    j = int(np.argmin(np.abs(np.where(np.isfinite(L.range), L.range, 1e9)
                                             - np.hypot(*c))))
                    C.append((i, c, v, max(float(L.sigma[j]), 0.02)))
        cat = (lambda xs, sh: np.concatenate(xs) if xs else np.zeros(sh))
        self.sp, self.ss = cat(P, (0, 2)), cat(S, 0)
        self.si, self.sl = cat(I, 0).astype(int), cat(E, 0).astype(int)
        self.corners = C

    def _matches(self, matches, poses, cams):
        self.mt = []
        for (i, j), (a, b) in matches.items():
            if not (self.placed[i] and self.placed[j]) or self.spot[i] == self.spot[j] or not len(a):
                continue
            sig = self.p.match_px / (cams[i] if cams is not None else 500.0)
            r = self._epi(poses[i], poses[j], a, b)
            keep = np.flatnonzero(np.abs(r) < self.p.match_gate * sig)[: self.p.max_matches]
            if len(keep) >= 5:   # one pair's matches share its model errors
                self.mt.append((i, j, a[keep], b[keep],
                                sig * np.sqrt(max(1.0, len(keep) / self.p.match_eff)),
                                poses[j, :2] - poses[i, :2]))

    def _tilts(self, tilt):
        """Each photo in the matches whose gravity's tilt has a 1-sigma ``tilt[i]`` > 0
        (radians per axis) gets that tilt, about its level x and z axes, as two unknowns
        after the others, held near 0 by it: its bearings turn with it in its matches'
        residuals, which then do not take a tilt error for a turn (the rear photos of dev
        room zr_r10, a phone's gravity 0.1-0.6 deg off: 1.7-2.0 deg off in yaw at
        +-0.35-0.53 before)."""
        self.tilt_sig = np.zeros(self.N) if tilt is None else np.asarray(tilt, float)
        who = sorted({k for i, j, *_ in self.mt for k in (i, j) if self.tilt_sig[k] > 0})
        n = len(self.x0)
        self.tilt_ix = {k: (n + 2 * q, n + 2 * q + 1) for q, k in enumerate(who)}
        self.x0 = np.concatenate([self.x0, np.zeros(2 * len(who))])

    def _tilts_of(self, x) -> dict:
        """{photo: (3, 3) the transposed rotation its tilt unknowns in ``x`` give its level
        bearings}, each made once per evaluation (a photo takes part in several pairs)."""
        return {k: planar.rot_tilt(*x[list(c)]).T for k, c in self.tilt_ix.items()}

    @staticmethod
    def _epi(pi, pj, a, b):
        pi, pj = np.asarray(pi, float), np.asarray(pj, float)
        yaw = pj[2] - pi[2]
        t2 = register.rot2(np.array([-pi[2]]), (pj[:2] - pi[:2])[None])[0, 0]
        return planar.epipolar_residuals(yaw, np.array([t2[0], 0.0, t2[1]]), a, b)

    # ------------------------------------------------------------------ residuals
    def residuals(self, x):
        n, d = self.lines(x)
        out = []
        if len(self.sp):
            C = np.zeros((len(self.sp), 2))
            Y = np.zeros(len(self.sp))
            for i in np.unique(self.si):
                c, y = self.pose(x, i)
                C[self.si == i], Y[self.si == i] = c, y
            cs, sn = np.cos(Y), np.sin(Y)
            q = np.column_stack([cs * self.sp[:, 0] + sn * self.sp[:, 1],
                                 -sn * self.sp[:, 0] + cs * self.sp[:, 1]]) + C
            out.append((np.einsum("ij,ij->i", q, n[self.sl]) - d[self.sl]) / self.ss)
        if self.corners:
            V = vertices_of(n, d, self.line, self.V0)
            for i, cq, v, sig in self.corners:
                c, y = self.pose(x, i)
                w = register.rot2(np.array([y]), cq[None])[0, 0] + c
                out.append((w - V[v]) / sig)
        for i, j, yaw, sig in self._links:
            yi = self.pose(x, i)[1]
            yj = self.pose(x, j)[1]
            out.append(np.atleast_1d(np.angle(np.exp(1j * (yj - yi - yaw))) / sig))
        if len(self.prior0):
            out.append((x[:len(self.prior0)] - self.prior0) / self.p.prior_m)
        tilt = self._tilts_of(x)
        for i, j, a, b, sig, base in self.mt:   # the turn only: the baseline as placed
            yi, yj = self.pose(x, i)[1], self.pose(x, j)[1]
            a, b = (a @ tilt[i] if i in tilt else a), (b @ tilt[j] if j in tilt else b)
            out.append(self._epi((0.0, 0.0, yi), (base[0], base[1], yj), a, b) / sig)
        for k, c in self.tilt_ix.items():
            out.append(x[list(c)] / self.tilt_sig[k])
        return np.concatenate(out) if out else np.zeros(0)
