"""Planar camera motion between two photos (paper step 5, eqs. 5-8, and a robust default).

Frames and units (DESIGN.md): each photo has a level frame (y down along gravity, z the
optical axis projected on the horizontal plane, x right); the motion of a pair (A, B) is
the pose of camera B in A's level frame: ``X_A = R_y(yaw) X_B + t`` for level-frame points,
R_y(yaw) = [[c, 0, s], [0, 1, 0], [-s, 0, c]], t = (x, dy, z) metres, yaw in radians
(> 0: B turned right of A). ``dy = h_A - h_B`` is known from the two camera heights, so
the unknowns are (yaw, x, z): 3 DOF.

Inputs per match i: unit level bearings a_i (A), b_i (B) and, where a photo's scene
(chosen hypothesis) gives one, the lifted 3D point P_A,i / P_B,i in that photo's level
frame with its 1-sigma radius (``features.Lifted``).

Estimators (``METHODS``):

* ``findme`` (default): gravity-aware epipolar RANSAC (2-point planar solver when dy = 0,
  3-point solver with a free vertical baseline otherwise) gives yaw and the baseline
  direction; the metric scale comes from the lifted points (1-D consensus); both scored
  together, then a robust Gauss-Newton refinement of (yaw, x, z) on the epipolar residuals
  of all inliers and the transfer residuals of the lifted inliers.
* ``lifted``: 2-point RANSAC on matches lifted in both photos and projected to the floor,
  weighted closed-form 2-D rigid alignment (Kabsch), refit on the inliers.
* ``paper``: the paper's estimator as written: yaw = 1/Z-weighted mean of the bearing
  differences (eq. 5), translation = 1/Z-weighted mean of the differences P_A - R P_B
  (eqs. 6-8), on the geometrically verified matches lifted in both photos.

Every estimate carries its inliers and a 1-sigma uncertainty. Degenerate input raises
``MotionError`` naming the cause. Pure: numpy in, numbers out (randomness is seeded).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .camera import Camera
from .errors import InputError, MotionError
from .features import Lifted, Matches

METHODS = ("findme", "lifted", "paper")


@dataclass(frozen=True)
class MotionParams:
    """Thresholds (pixels, metres) and RANSAC settings.

    Attributes:
        thr_px: epipolar inlier threshold, pixels (converted to angle with the focal length).
        iters: RANSAC samples.
        min_matches: fewer putative matches than this: no common view.
        min_inliers: fewer geometrically consistent matches than this: no common view.
        min_parallax_px: median match displacement below this: the photos are identical.
        lift_floor_m: 2-D inlier threshold floor of the ``lifted`` estimator, metres.
        seed: RANSAC random seed (results are reproducible).
    """

    thr_px: float = 2.0
    iters: int = 400
    min_matches: int = 8
    min_inliers: int = 6
    min_parallax_px: float = 0.3
    lift_floor_m: float = 0.05
    seed: int = 0


@dataclass(frozen=True)
class PlanarMotion:
    """Pose of camera B in camera A's level frame, with 1-sigma uncertainties.

    Attributes:
        x, z: B's centre, metres (x right, z forward of A's level frame).
        yaw: heading of B relative to A, radians (> 0 turned right).
        dy: vertical offset h_A - h_B used (metres, > 0: B lower); an input, not estimated.
        sigma_x, sigma_z, sigma_yaw: 1-sigma of x, z (m) and yaw (rad).
        inliers: (M,) bool over the matches given: consistent with the estimate.
        n_scale: lifted points that fixed the metric scale.
        method: the estimator.
    """

    x: float
    z: float
    yaw: float
    dy: float
    sigma_x: float
    sigma_z: float
    sigma_yaw: float
    inliers: np.ndarray
    n_scale: int
    method: str

    @property
    def n_inliers(self) -> int:
        return int(np.count_nonzero(self.inliers))


def rot_y(yaw: float) -> np.ndarray:
    """(3, 3) level_A <- level_B rotation R_y(yaw)."""
    c, s = np.cos(yaw), np.sin(yaw)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


def bearings(camera: Camera, pixels) -> np.ndarray:
    """(N, 2) pixels -> (N, 3) unit ray directions in the camera's level frame."""
    r = camera.rays_level(pixels)
    return r / np.linalg.norm(r, axis=1, keepdims=True)


# ---------------------------------------------------------------------------- minimal solvers
def solve_planar_2pt(a: np.ndarray, b: np.ndarray) -> list[tuple[float, np.ndarray]]:
    """Yaw and unit horizontal baseline from 2 matches (dy = 0; Ortin & Montiel 2001).

    With t = (sin phi, 0, cos phi) and psi = phi - yaw, a^T [t]x R_y b = 0 is linear in
    v = (cos phi, sin phi, cos psi, sin psi): row (-a_x b_y, a_z b_y, a_y b_x, -a_y b_z).
    v lies in the 2-D null space of the 2 rows; |v_01| = |v_23| = 1 gives a quadratic.
    The sign of t is left to the caller (cheirality). Returns up to 2 (yaw, t).
    """
    A = np.column_stack([-a[:, 0] * b[:, 1], a[:, 2] * b[:, 1], a[:, 1] * b[:, 0],
                         -a[:, 1] * b[:, 2]])
    n1, n2 = np.linalg.svd(A)[2][2:]
    quad = lambda u, w: np.array([u @ u, 2 * u @ w, w @ w])  # noqa: E731
    d = quad(n1[:2], n2[:2]) - quad(n1[2:], n2[2:])
    if abs(d[0]) > 1e-12:
        ratios = [(r.real, 1.0) for r in np.roots(d) if abs(r.imag) < 1e-9]
    else:
        ratios = [(1.0, 0.0)] + ([(-d[2] / d[1], 1.0)] if abs(d[1]) > 1e-12 else [])
    out = []
    for al, be in ratios:
        v = al * n1 + be * n2
        if np.linalg.norm(v[:2]) < 1e-12:
            continue
        phi, psi = np.arctan2(v[1], v[0]), np.arctan2(v[3], v[2])
        out.append((float(np.angle(np.exp(1j * (phi - psi)))),
                    np.array([np.sin(phi), 0.0, np.cos(phi)])))
    return out


def solve_gravity_3pt(a: np.ndarray, b: np.ndarray) -> list[tuple[float, np.ndarray]]:
    """Yaw and unit 3-D baseline from 3 matches (known vertical, free dy).

    Each match gives t . m_i = 0 with m_i = (R_y b_i) x a_i = c p_i + s q_i + r_i, so
    det[m_1, m_2, m_3] = 0: a cubic in (c, s) = (cos, sin yaw), a sextic in tan(yaw / 2).
    Returns up to 6 (yaw, t), t up to sign.
    """
    z = np.zeros(3)
    K = np.stack([np.cross(np.column_stack([b[:, 0], z, b[:, 2]]), a),     # p (cos)
                  np.cross(np.column_stack([b[:, 2], z, -b[:, 0]]), a),    # q (sin)
                  np.cross(np.column_stack([z, b[:, 1], z]), a)])          # r (1)
    basis = ([-1.0, 0.0, 1.0], [2.0, 0.0], [1.0, 0.0, 1.0])  # c, s, 1 times (1 + x^2)
    coeffs = np.zeros(7)
    for ks in np.ndindex(3, 3, 3):
        det = np.linalg.det(np.stack([K[ks[0], 0], K[ks[1], 1], K[ks[2], 2]]))
        term = np.polymul(np.polymul(basis[ks[0]], basis[ks[1]]), basis[ks[2]])
        coeffs[7 - len(term):] += det * term
    coeffs = np.trim_zeros(coeffs, "f")
    out = []
    for x in (np.roots(coeffs) if len(coeffs) > 1 else []):
        if abs(x.imag) < 1e-7:
            yaw = 2.0 * np.arctan(x.real)
            t = np.linalg.svd(np.cross(b @ rot_y(yaw).T, a))[2][2]
            out.append((float(yaw), t / np.linalg.norm(t)))
    return out


# ---------------------------------------------------------------------------- residuals
def epipolar_residuals(yaw: float, t: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """(N,) signed angle (rad, Sampson-like) of each match from its epipolar plane."""
    Rb = b @ rot_y(yaw).T
    n1, n2 = np.cross(t, Rb), np.cross(t, a)
    den = np.sqrt(0.5 * (np.einsum("ij,ij->i", n1, n1) + np.einsum("ij,ij->i", n2, n2)))
    return np.einsum("ij,ij->i", a, n1) / np.maximum(den, 1e-12)


def depths(yaw: float, t: np.ndarray, a: np.ndarray, b: np.ndarray):
    """Least-squares depths (la, lb) along a and b with la a = t + lb R b."""
    Rb = b @ rot_y(yaw).T
    ab, at, bt = np.einsum("ij,ij->i", a, Rb), a @ t, Rb @ t
    det = np.maximum(1.0 - ab * ab, 1e-12)
    return (at - ab * bt) / det, (ab * at - bt) / det


# ---------------------------------------------------------------------------- estimation
@dataclass(frozen=True)
class _Pair:
    """Bearings (M, 3), lifted points of both photos, dy and the angular pixel sigma."""

    a: np.ndarray
    b: np.ndarray
    la: Lifted
    lb: Lifted
    dy: float
    sig: float  # one pixel in radians


def estimate(matches: Matches, cam_a: Camera, cam_b: Camera, h_a: float, h_b: float,
             lifted_a: Lifted | None, lifted_b: Lifted | None, method: str = "findme",
             params: MotionParams = MotionParams()) -> PlanarMotion:
    """Planar motion of B in A's level frame from matches and the lifted points.

    Args:
        matches: putative matches (pixels of A and B).
        cam_a, cam_b: intrinsics and gravity of each photo.
        h_a, h_b: camera heights above the floor, metres (dy = h_a - h_b).
        lifted_a, lifted_b: 3D of each match in each photo (``features.lift``), None for a
            photo without a usable hypothesis.
        method: one of ``METHODS``.

    Raises:
        MotionError: too few matches, no common view, identical photos, no 3D for scale.
    """
    if method not in METHODS:
        raise InputError(f"unknown motion method {method!r}; choose one of {', '.join(METHODS)}")
    n = len(matches)
    if n < params.min_matches:
        raise MotionError(f"only {n} feature matches between the photos ({matches.n_a} and "
                          f"{matches.n_b} keypoints; need {params.min_matches}): they show "
                          "too little common texture")
    disp = np.linalg.norm(matches.ua - matches.ub, axis=1)
    if np.mean(disp < params.min_parallax_px) > 0.8:
        raise MotionError("the two photos are identical (their features did not move), so "
                          "there is no motion to measure")
    P = _Pair(bearings(cam_a, matches.ua), bearings(cam_b, matches.ub),
              lifted_a if lifted_a is not None else Lifted.empty(n),
              lifted_b if lifted_b is not None else Lifted.empty(n),
              float(h_a - h_b), 1.0 / np.sqrt(cam_a.fx * cam_b.fx))
    rng = np.random.default_rng(params.seed)
    if method == "lifted":
        return _lifted(P, params, rng)
    yaw, d, inl = _epipolar_ransac(P, params, rng)
    if method == "paper":
        return _paper(P, yaw, inl)
    return _findme(P, yaw, d, inl, params)


def _no_common_view(k: int, n: int) -> MotionError:
    return MotionError(f"the photos have no common view: only {k} of {n} matches agree on "
                       "one camera motion")


def _epipolar_ransac(P: _Pair, params: MotionParams, rng):
    """(yaw, unit baseline t, inlier mask) maximising the MSAC score of the epipolar
    residuals plus the 1-D scale consensus of the lifted points."""
    n, thr = len(P.a), params.thr_px * P.sig
    planar = abs(P.dy) < 1e-6
    k = 2 if planar else 3
    solver = solve_planar_2pt if planar else solve_gravity_3pt
    best, best_score = None, -1.0
    for _ in range(params.iters):
        idx = rng.choice(n, k, replace=False)
        for yaw, t in solver(P.a[idx], P.b[idx]):
            r = np.abs(epipolar_residuals(yaw, t, P.a, P.b))
            inl = r < thr
            la, lb = depths(yaw, t, P.a[inl], P.b[inl])
            if np.sum((la > 0) & (lb > 0)) < np.sum((la < 0) & (lb < 0)):
                t = -t
                la, lb = -la, -lb
            front = np.zeros(n, bool)
            front[np.flatnonzero(inl)] = (la > 0) & (lb > 0)
            score = np.sum(np.maximum(0.0, 1.0 - (r[front] / thr) ** 2))
            if score > best_score:
                best, best_score = (yaw, t, front), score
    if best is None or best[2].sum() < params.min_inliers:
        raise _no_common_view(0 if best is None else int(best[2].sum()), n)
    return best


def _scale_obs(P: _Pair, yaw, h, inl):
    """Per lifted inlier: the baseline length s along the unit horizontal h that puts the
    point on the other photo's ray, and its 1-sigma (relative error = relative depth error
    of the point (+) triangulation error of the pixel). Returns (idx_a, idx_b, s, sigma)."""
    R, y = rot_y(yaw), np.array([0.0, P.dy, 0.0])
    out = []
    for L, into_b in ((P.la, True), (P.lb, False)):
        idx = np.flatnonzero(inl & L.valid)
        pts, sig = L.points[idx], L.sigma[idx]
        if into_b:  # P_A - dy y = s h + mu R b
            c, v = pts - y, P.b[idx] @ R.T
        else:       # -(R P_B + dy y) = s h + mu (-a)
            c, v = -(pts @ R.T + y), P.a[idx]
        hv = v @ h
        den = np.maximum(1.0 - hv ** 2, 1e-9)
        s = (c @ h - hv * np.einsum("ij,ij->i", v, c)) / den
        rel = np.hypot(sig / np.linalg.norm(pts, axis=1), 2.0 * P.sig / np.sqrt(den))
        out.append((idx, s, rel * np.abs(s) + 1e-3))
    return out


def _consensus_scale(obs) -> tuple[float, np.ndarray, np.ndarray]:
    """1-D MSAC over the scale observations: (s, inlier idx of A, inlier idx of B)."""
    s = np.concatenate([o[1] for o in obs])
    sg = np.concatenate([o[2] for o in obs])
    if len(s) == 0:
        raise MotionError("no matched point lies on the floor or on a chosen wall in either "
                          "photo, so the distance between the photos cannot be measured")
    score = np.maximum(0.0, 1.0 - ((s[None, :] - s[:, None]) / (2.5 * sg[None, :])) ** 2).sum(1)
    s0 = s[np.argmax(score)]
    ok = np.abs(s - s0) < 2.5 * sg
    s1 = float(np.sum(s[ok] / sg[ok] ** 2) / np.sum(1.0 / sg[ok] ** 2))
    na = len(obs[0][0])
    return s1, obs[0][0][ok[:na]], obs[1][0][ok[na:]]


def _findme(P: _Pair, yaw, t, inl, params: MotionParams) -> PlanarMotion:
    h = np.array([t[0], 0.0, t[2]])
    h = h / max(np.linalg.norm(h), 1e-12)
    s, ia, ib = _consensus_scale(_scale_obs(P, yaw, h, inl))
    p = np.array([yaw, s * h[0], s * h[2]])
    e_idx = np.flatnonzero(inl)

    def resid(q):
        tq = np.array([q[1], P.dy, q[2]])
        r = [epipolar_residuals(q[0], tq, P.a[e_idx], P.b[e_idx]) / P.sig]
        for idx, L, rays, into_b in ((ia, P.la, P.b, True), (ib, P.lb, P.a, False)):
            r.append(_transfer(q[0], tq, L.points[idx], L.sigma[idx], rays[idx], into_b, P.sig))
        return np.concatenate(r)

    p, cov = _gauss_newton(resid, p)
    tq = np.array([p[1], P.dy, p[2]])
    r = np.abs(epipolar_residuals(p[0], tq, P.a, P.b))
    la, lb = depths(p[0], tq, P.a, P.b)
    final = (r < params.thr_px * P.sig) & (la > 0) & (lb > 0)
    return _result(p, P.dy, cov, final, len(ia) + len(ib), "findme")


def _transfer(yaw, t, pts, sig, rays, into_b, pix):
    """Angle (rad) between each observed ray and its lifted point moved into the other
    photo, divided by its sigma: the pixel part (+) the point's depth error seen across."""
    R = rot_y(yaw)
    Q = (pts - t) @ R if into_b else pts @ R.T + t
    dist = np.maximum(np.linalg.norm(Q, axis=1), 1e-9)
    Qn = Q / dist[:, None]
    sin_ang = np.linalg.norm(np.cross(Qn, rays), axis=1)
    ang = np.where(np.einsum("ij,ij->i", Qn, rays) > 0, np.arcsin(np.minimum(sin_ang, 1.0)), np.pi)
    own = pts / np.linalg.norm(pts, axis=1, keepdims=True)  # the lifting ray's direction
    own = own @ R if into_b else own @ R.T
    sin_par = np.linalg.norm(np.cross(own, rays), axis=1)  # the depth error's lever arm
    return ang / np.hypot(pix, sig * sin_par / dist)


def _gauss_newton(resid, p, iters: int = 15, c: float = 2.5):
    """Robust (Cauchy, c sigmas) Gauss-Newton with a numeric Jacobian. Returns the
    parameters and their covariance (inflated by the robust chi^2 per dof when > 1)."""
    step = np.array([1e-6, 1e-6, 1e-6])
    for _ in range(iters):
        r = resid(p)
        J = np.column_stack([(resid(p + np.eye(3)[j] * step[j]) - r) / step[j] for j in range(3)])
        w = 1.0 / (1.0 + (r / c) ** 2)
        H = J.T @ (w[:, None] * J)
        dp = -np.linalg.lstsq(H, J.T @ (w * r), rcond=None)[0]
        p = p + dp
        if np.max(np.abs(dp)) < 1e-9:
            break
    r = resid(p)
    w = 1.0 / (1.0 + (r / c) ** 2)
    H = J.T @ (w[:, None] * J)
    chi = float(np.sum(w * r * r)) / max(len(r) - 3, 1)
    cov = np.linalg.pinv(H) * max(chi, 1.0)
    return p, cov


def _result(p, dy, cov, inliers, n_scale, method) -> PlanarMotion:
    sd = np.sqrt(np.maximum(np.diag(cov), 0.0))
    return PlanarMotion(float(p[1]), float(p[2]), float(np.angle(np.exp(1j * p[0]))), dy,
                        float(sd[1]), float(sd[2]), float(sd[0]), inliers, int(n_scale), method)


def _paper(P: _Pair, yaw0, inl) -> PlanarMotion:
    """Eqs. 5-8 on the verified matches lifted in both photos (floor projection x, z)."""
    idx = np.flatnonzero(inl & P.la.valid & P.lb.valid)
    if len(idx) == 0:
        raise MotionError("no verified match has a 3D point in both photos (floor or chosen "
                          "wall), so the paper's estimator has nothing to average")
    A, B = P.la.points[idx][:, [0, 2]], P.lb.points[idx][:, [0, 2]]
    w = 2.0 / (A[:, 1] + B[:, 1])                                   # 1 / Z
    d = np.angle(np.exp(1j * (np.arctan2(A[:, 0], A[:, 1]) - np.arctan2(B[:, 0], B[:, 1]))))
    yaw = float(np.sum(w * d) / np.sum(w))                          # eq. 5
    c, s = np.cos(yaw), np.sin(yaw)
    T = A - np.column_stack([c * B[:, 0] + s * B[:, 1], -s * B[:, 0] + c * B[:, 1]])
    t = (w[:, None] * T).sum(0) / np.sum(w)                         # eqs. 6-8
    neff = np.sum(w) ** 2 / np.sum(w ** 2)
    sd = lambda x, m: np.sqrt(np.sum(w * (x - m) ** 2) / np.sum(w) / neff)  # noqa: E731
    cov = np.diag([sd(d, yaw), sd(T[:, 0], t[0]), sd(T[:, 1], t[1])]) ** 2
    mask = np.zeros(len(P.a), bool)
    mask[idx] = True
    return _result([yaw, t[0], t[1]], P.dy, cov, mask, len(idx), "paper")


def _kabsch2(A, B, w):
    """Weighted 2-D rigid alignment A ~ R B + t: (yaw, t (2,)), R = R_y(yaw) on (x, z)."""
    ca, cb = (w[:, None] * A).sum(0) / w.sum(), (w[:, None] * B).sum(0) / w.sum()
    a, b = A - ca, B - cb
    # R_y on (x, z): x' = c x + s z, z' = -s x + c z -> maximise sum w a.(R b)
    num = np.sum(w * (a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0]))
    den = np.sum(w * (a[:, 0] * b[:, 0] + a[:, 1] * b[:, 1]))
    yaw = float(np.arctan2(num, den))
    c, s = np.cos(yaw), np.sin(yaw)
    return yaw, ca - np.array([c * cb[0] + s * cb[1], -s * cb[0] + c * cb[1]])


def _lifted(P: _Pair, params: MotionParams, rng) -> PlanarMotion:
    """2-point RANSAC + weighted Kabsch on matches lifted in both photos (floor plane)."""
    idx = np.flatnonzero(P.la.valid & P.lb.valid)
    if len(idx) < 2:
        raise MotionError(f"only {len(idx)} matches have a 3D point in both photos (floor or "
                          "chosen wall); the lifted estimator needs 2")
    A, B = P.la.points[idx][:, [0, 2]], P.lb.points[idx][:, [0, 2]]
    sig = np.maximum(np.hypot(P.la.sigma[idx], P.lb.sigma[idx]), params.lift_floor_m)
    w = 1.0 / sig ** 2

    def res(yaw, t):
        c, s = np.cos(yaw), np.sin(yaw)
        RB = np.column_stack([c * B[:, 0] + s * B[:, 1], -s * B[:, 0] + c * B[:, 1]])
        return np.linalg.norm(A - RB - t, axis=1) / sig

    best, best_score = None, -1.0
    for _ in range(params.iters):
        k = rng.choice(len(idx), 2, replace=False)
        yaw, t = _kabsch2(A[k], B[k], np.ones(2))
        score = np.sum(np.maximum(0.0, 1.0 - (res(yaw, t) / 3.0) ** 2))
        if score > best_score:
            best, best_score = (yaw, t), score
    for _ in range(3):
        ok = res(*best) < 3.0
        best = _kabsch2(A[ok], B[ok], w[ok])
    ok = res(*best) < 3.0
    if ok.sum() < 2:
        raise _no_common_view(int(ok.sum()), len(idx))
    neff = max(ok.sum() - 1.0, 1.0)
    sx = np.sqrt(1.0 / np.sum(w[ok])) * np.sqrt(max(np.mean(res(*best)[ok] ** 2), 1.0))
    spread = np.sqrt(np.sum(w[ok] * np.sum((B[ok] - B[ok].mean(0)) ** 2, 1)))
    cov = np.diag([(sx * np.sqrt(np.sum(w[ok])) / max(spread, 1e-9)) ** 2, sx ** 2, sx ** 2])
    mask = np.zeros(len(P.a), bool)
    mask[idx[ok]] = True
    del neff
    return _result([best[0], best[1][0], best[1][1]], P.dy, cov, mask, int(ok.sum()), "lifted")
