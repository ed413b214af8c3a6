"""Planar-motion geometry: rotations about gravity, minimal solvers, 2-D alignment and the
residuals the estimators in ``motion`` score hypotheses with.

Frames (DESIGN.md): each photo has a level frame (y down along gravity, z the optical axis
projected on the horizontal plane, x right). The motion of (A, B) maps B's level frame into
A's: X_A = R_y(yaw) X_B + t, R_y(yaw) = [[c, 0, s], [0, 1, 0], [-s, 0, c]] (yaw radians,
> 0: B turned right of A), t = (x, dy, z) metres. Bearings are unit level-frame rays.
The epipolar constraint of a match with bearings a (in A) and b (in B) is
a^T [t]x R_y(yaw) b = 0 (gravity known, so 3 DOF remain; 2 without vertical motion).
"""

from __future__ import annotations

import numpy as np

from findme_core.geometry.camera import Camera


def wrap(a):
    """Angle(s) in radians wrapped to (-pi, pi]."""
    return np.angle(np.exp(1j * np.asarray(a, float)))


def rot_y(yaw) -> np.ndarray:
    """(3, 3) level_A <- level_B rotation R_y(yaw); (C, 3, 3) for C yaws."""
    c, s = np.cos(yaw), np.sin(yaw)
    z, o = np.zeros_like(c), np.ones_like(c)
    return np.stack([np.stack([c, z, s], -1), np.stack([z, o, z], -1),
                     np.stack([-s, z, c], -1)], -2)


def rot_tilt(pitch: float, roll: float) -> np.ndarray:
    """(3, 3) rotation of level-frame vectors by gravity tilted ``pitch`` about x and
    ``roll`` about z (radians): R_x(pitch) R_z(roll)."""
    cp, sp, cr, sr = np.cos(pitch), np.sin(pitch), np.cos(roll), np.sin(roll)
    return np.array([[1.0, 0.0, 0.0], [0.0, cp, -sp], [0.0, sp, cp]]) @ np.array(
        [[cr, -sr, 0.0], [sr, cr, 0.0], [0.0, 0.0, 1.0]])


def _rotate(yaw, v, inverse: bool = False) -> np.ndarray:
    """R_y(yaw) v (or R_y^T v) for C yaws (C,) and vectors (N, 3) or (C, N, 3): (C, N, 3)."""
    c, s = np.cos(yaw)[:, None], np.sin(yaw)[:, None] * (-1.0 if inverse else 1.0)
    x, y, z = v[..., 0], v[..., 1], v[..., 2]
    out = np.empty(np.broadcast_shapes(c.shape, x.shape) + (3,))  # filled, not stacked: 2x faster
    out[..., 0] = c * x + s * z
    out[..., 1] = y
    out[..., 2] = c * z - s * x
    return out


def _rot2(yaw, B):
    """R_y(yaw) on floor points (..., 2) = (x, z)."""
    c, s = np.cos(yaw), np.sin(yaw)
    return np.stack([c * B[..., 0] + s * B[..., 1], -s * B[..., 0] + c * B[..., 1]], -1)


def _cross(u, v):
    """np.cross over the last axis with broadcasting, without its overhead (filled in place:
    5x faster than stacking for the (C, N, 3) arrays of RANSAC scoring)."""
    out = np.empty(np.broadcast_shapes(u.shape, v.shape))
    out[..., 0] = u[..., 1] * v[..., 2] - u[..., 2] * v[..., 1]
    out[..., 1] = u[..., 2] * v[..., 0] - u[..., 0] * v[..., 2]
    out[..., 2] = u[..., 0] * v[..., 1] - u[..., 1] * v[..., 0]
    return out


def _dot(u, v):
    """Dot product over the last axis (3) with broadcasting: explicit terms, 5-10x faster
    than np.sum(u * v, -1) whose reduction over a length-3 axis dominates the estimators."""
    return u[..., 0] * v[..., 0] + u[..., 1] * v[..., 1] + u[..., 2] * v[..., 2]


def _norm(u):
    """Euclidean norm over the last axis (3)."""
    return np.sqrt(_dot(u, u))


def bearings(camera: Camera, pixels) -> np.ndarray:
    """(N, 2) pixels -> (N, 3) unit ray directions in the camera's level frame."""
    r = camera.rays_level(pixels)
    return r / np.linalg.norm(r, axis=1, keepdims=True)


def solve_planar_2pt(a: np.ndarray, b: np.ndarray):
    """Yaw and unit horizontal baseline from S samples of 2 matches, a, b (S, 2, 3).

    With t = (sin phi, 0, cos phi) and psi = phi - yaw, a^T [t]x R_y b = 0 is linear in
    v = (cos phi, sin phi, cos psi, sin psi): row (-a_x b_y, a_z b_y, a_y b_x, -a_y b_z)
    (Ortin & Montiel 2001). v = x n1 + n2 in the null space of the 2 rows, and
    |v_01| = |v_23| = 1 gives a quadratic in x. Returns yaw (C,), t (C, 3) up to sign and
    the sample of each (C,)."""
    A = np.stack([-a[..., 0] * b[..., 1], a[..., 2] * b[..., 1], a[..., 1] * b[..., 0],
                  -a[..., 1] * b[..., 2]], -1)
    V = np.linalg.svd(A)[2]
    n1, n2 = V[:, 2], V[:, 3]
    d = [np.sum(u[:, :2] * w[:, :2], 1) - np.sum(u[:, 2:] * w[:, 2:], 1)
         for u, w in ((n1, n1), (n1, n2), (n2, n2))]
    disc = (2 * d[1]) ** 2 - 4 * d[0] * d[2]
    ok = (disc >= 0) & (np.abs(d[0]) > 1e-12)
    yaws, ts = [], []
    for sgn in (-1.0, 1.0):
        x = (-2 * d[1][ok] + sgn * np.sqrt(disc[ok])) / (2 * d[0][ok])
        v = x[:, None] * n1[ok] + n2[ok]
        phi, psi = np.arctan2(v[:, 1], v[:, 0]), np.arctan2(v[:, 3], v[:, 2])
        yaws.append(phi - psi)
        ts.append(np.stack([np.sin(phi), np.zeros_like(phi), np.cos(phi)], 1))
    src = np.tile(np.flatnonzero(ok), 2)
    return np.angle(np.exp(1j * np.concatenate(yaws))), np.concatenate(ts), src


_BASIS = ([-1.0, 0.0, 1.0], [2.0, 0.0], [1.0, 0.0, 1.0])  # cos, sin, 1 times (1 + x^2)
_POLY = np.array([np.pad(p, (7 - len(p), 0)) for p in (
    np.polymul(np.polymul(_BASIS[i], _BASIS[j]), _BASIS[k]) for i, j, k in np.ndindex(3, 3, 3))])


def solve_gravity_3pt(a: np.ndarray, b: np.ndarray):
    """Yaw and unit 3-D baseline from S samples of 3 matches, a, b (S, 3, 3) (known vertical,
    free dy). Each match gives t . m_i = 0 with m_i = (R_y b_i) x a_i = c p_i + s q_i + r_i,
    so det[m_1, m_2, m_3] = 0: a cubic in (c, s) = (cos, sin yaw), a sextic in tan(yaw / 2)
    (roots: companion matrices). Returns yaw (C,), t (C, 3) up to sign, the sample (C,)."""
    z = np.zeros(b.shape[:2])
    K = np.stack([_cross(np.stack([b[..., 0], z, b[..., 2]], -1), a),
                  _cross(np.stack([b[..., 2], z, -b[..., 0]], -1), a),
                  _cross(np.stack([z, b[..., 1], z], -1), a)], 1)      # (S, kind, point, 3)
    # det of every (i, j, k) choice of kinds at once, in np.ndindex(3, 3, 3) order
    cr = _cross(K[:, :, 1, None, :], K[:, None, :, 2, :])                # (S, j, k, 3)
    dets = np.sum(K[:, :, 0, None, None, :] * cr[:, None], -1).reshape(len(K), 27)
    coeffs = dets @ _POLY
    ok = np.abs(coeffs[:, 0]) > 1e-9 * np.abs(coeffs).max(1)  # else a root at yaw = pi: skip
    comp = np.zeros((int(ok.sum()), 6, 6))
    comp[:, 0, :] = -coeffs[ok, 1:] / coeffs[ok, :1]
    comp[:, np.arange(1, 6), np.arange(5)] = 1.0
    x = np.linalg.eigvals(comp)
    real = np.abs(x.imag) < 1e-7 * np.maximum(1.0, np.abs(x.real))
    src = np.repeat(np.flatnonzero(ok), 6).reshape(-1, 6)[real]
    yaw = 2.0 * np.arctan(x.real[real])
    m = _cross(_rotate(yaw, b[src]), a[src])
    t = _cross(m[:, 0], m[:, 1])
    return yaw, t / np.maximum(np.linalg.norm(t, axis=1, keepdims=True), 1e-300), src


def kabsch_2d(A: np.ndarray, B: np.ndarray, w: np.ndarray) -> tuple[float, np.ndarray]:
    """Weighted 2-D rigid alignment of floor points (x, z), A ~ R_y(yaw) B + t, closed form.
    Returns (yaw, t (2,))."""
    ca, cb = w @ A / w.sum(), w @ B / w.sum()
    a, b = A - ca, B - cb
    yaw = float(np.arctan2(w @ (a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0]),
                           w @ (a[:, 0] * b[:, 0] + a[:, 1] * b[:, 1])))
    return yaw, ca - _rot2(yaw, cb)


def _kabsch_pairs(A, B, j):
    """``kabsch_2d`` of the 2-point samples j (S, 2): yaw (S,), t (S, 2)."""
    dA, dB = A[j[:, 1]] - A[j[:, 0]], B[j[:, 1]] - B[j[:, 0]]
    yaw = np.arctan2(dA[:, 0] * dB[:, 1] - dA[:, 1] * dB[:, 0], np.sum(dA * dB, 1))
    return yaw, A[j].mean(1) - _rot2(yaw[:, None], B[j]).mean(1)


# ---------------------------------------------------------------------------- residuals
def epipolar_residuals(yaw, t, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Signed angle (rad, Sampson-like) of each match from its epipolar plane,
    a . (t x R b) / rms(|t x R b|, |t x a|): (M,) for one motion, (C, M) for C yaws (C,)
    and baselines (C, 3)."""
    # by components, (C, M) each (the arithmetic of _rotate, _cross and _dot, without their
    # strided (C, M, 3) arrays), in place: the same operations in the same order, without a
    # new array per operation (RANSAC scores ~200 candidates x all matches at once)
    T = np.atleast_2d(t)
    tx, ty, tz = T[:, 0, None], T[:, 1, None], T[:, 2, None]
    y1 = np.atleast_1d(yaw)
    c, s = np.cos(y1)[:, None], np.sin(y1)[:, None]
    ax, ay, az = a[:, 0], a[:, 1], a[:, 2]
    bx, by, bz = b[:, 0], b[:, 1], b[:, 2]
    mul = np.multiply
    w, rx, rz, n1x, n1y = np.empty((5, max(len(y1), len(T)), len(a)))   # w: scratch
    mul(c, bx, out=rx)
    rx += mul(s, bz, out=w)                                   # R_y(yaw) b; its y is b's
    mul(c, bz, out=rz)
    rz -= mul(s, bx, out=w)
    mul(ty, rz, out=n1x)
    n1x -= mul(tz, by, out=w)                                 # n1 = t x R b
    mul(tz, rx, out=n1y)
    n1y -= mul(tx, rz, out=w)
    n1z = mul(tx, by, out=rz)
    n1z -= mul(ty, rx, out=w)
    num = mul(ax, n1x, out=rx)                                # a . n1
    num += mul(ay, n1y, out=w)
    num += mul(az, n1z, out=w)
    q1 = mul(n1x, n1x, out=n1x)                               # |n1|^2
    q1 += mul(n1y, n1y, out=w)
    q1 += mul(n1z, n1z, out=w)
    n2 = mul(ty, az, out=n1y)                                 # n2 = t x a
    n2 -= mul(tz, ay, out=w)
    q2 = mul(n2, n2, out=n1z)                                 # |n2|^2
    mul(tz, ax, out=n2)
    n2 -= mul(tx, az, out=w)
    q2 += mul(n2, n2, out=w)
    mul(tx, ay, out=n2)
    n2 -= mul(ty, ax, out=w)
    q2 += mul(n2, n2, out=w)
    q1 += q2
    q1 *= 0.5
    den = np.maximum(np.sqrt(q1, out=q1), 1e-12, out=q1)   # rms(|t x R b|, |t x a|)
    r = np.divide(num, den, out=num)
    return r[0] if np.ndim(yaw) == 0 else r


def turn_residuals(yaw, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Angle (rad) between each match's bearing a and R_y(yaw) b: how far a pure turn (two
    photos taken at one place) misses it; (C, M) for C yaws (C,). With no baseline the
    epipolar plane is undefined: ``epipolar_residuals`` puts every match of a true turn on
    it, whatever the baseline's direction, so a turn is scored by this instead."""
    Rb = _rotate(np.atleast_1d(yaw), b)
    return np.arccos(np.clip(_dot(a[None], Rb), -1.0, 1.0))


def depths(yaw, t, a: np.ndarray, b: np.ndarray):
    """Least-squares depths (la, lb) along a and b with la a = t + lb R_y b; shapes as in
    ``epipolar_residuals``."""
    Rb, T = _rotate(np.atleast_1d(yaw), b), np.atleast_2d(t)
    ab, at, bt = _dot(a[None], Rb), T @ a.T, _dot(Rb, T[:, None, :])
    det = np.maximum(1.0 - ab * ab, 1e-12)
    la, lb = (at - ab * bt) / det, (ab * at - bt) / det
    return (la[0], lb[0]) if np.ndim(yaw) == 0 else (la, lb)


def _turn(yaw, x, y, z, inverse: bool = False):
    """``_rotate`` by components: R_y(yaw) (or R_y^T) of vectors given as x, y, z arrays that
    broadcast against (C, 1); returns (x, y, z) (C, N)."""
    c, s = np.cos(yaw)[:, None], np.sin(yaw)[:, None] * (-1.0 if inverse else 1.0)
    return c * x + s * z, y, c * z - s * x


def _moved(yaw, t, pts, into_b: bool):
    """Lifted points (N, 3) of one photo in the other photo's level frame: (x, y, z) (C, N)
    each, for C yaws (C,) and t (C, 3)."""
    T = np.atleast_2d(t)
    tx, ty, tz = T[:, 0, None], T[:, 1, None], T[:, 2, None]
    px, py, pz = pts[:, 0], pts[:, 1], pts[:, 2]
    if into_b:
        return _turn(yaw, px - tx, py - ty, pz - tz, True)
    qx, qy, qz = _turn(yaw, px, py, pz)
    return qx + tx, qy + ty, qz + tz


def _norm3(x, y, z):
    """``_norm`` by components."""
    return np.sqrt(x * x + y * y + z * z)


def _cross_norm(x, y, z, rays):
    """|(x, y, z) x ray| for rays (N, 3) (``_norm(_cross(., rays))`` by components)."""
    rx, ry, rz = rays[:, 0], rays[:, 1], rays[:, 2]
    return _norm3(y * rz - z * ry, z * rx - x * rz, x * ry - y * rx)


def _spread(yaw, t, pts, sig, rays, into_b: bool, pix: float, dist=None):
    """hypot(1, each point's sigma (N,) along its own ray, seen across the observed ray of
    the other photo, in pixels): (C, N). ``dist``: the points' distances (C, N) from the other
    camera (``transfer_residuals``), computed when None."""
    y1 = np.atleast_1d(yaw)
    u = pts / np.maximum(_norm(pts), 1e-12)[:, None]
    own = _turn(y1, u[:, 0], u[:, 1], u[:, 2], into_b)
    if dist is None:
        dist = np.maximum(_norm3(*_moved(y1, t, pts, into_b)), 1e-9)
    return np.hypot(1.0, sig * _cross_norm(*own, rays) / dist / pix)


def transfer_residuals(yaw, t, pts, sig, rays, into_b: bool, pix: float, spread=None,
                       max_spread=None):
    """Lifted points (N, 3) of one photo moved into the other: angle to the observed rays
    (N, 3) in pixels over their ``_spread`` (computed when None, then capped at
    ``max_spread`` if given); 1000 for a point behind the camera. (N,) for one motion,
    (C, N) for C."""
    y1 = np.atleast_1d(yaw)
    qx, qy, qz = _moved(y1, t, pts, into_b)
    dist = np.maximum(_norm3(qx, qy, qz), 1e-9)
    if spread is None:
        spread = _spread(y1, t, pts, sig, rays, into_b, pix, dist)
        spread = spread if max_spread is None else np.minimum(spread, max_spread)
    sin_ray = _cross_norm(qx, qy, qz, rays) / dist
    front = qx * rays[:, 0] + qy * rays[:, 1] + qz * rays[:, 2]
    r = np.where(front > 0, sin_ray / pix / spread, 1000.0)
    return r[0] if np.ndim(yaw) == 0 else r


def _epipolar_terms(a, b, yaw, t, pix):
    """(C, M) epipolar residuals in pixels, and masks: in front of both cameras, behind
    both, no parallax (a ~ R b within 1 px: at infinity or a pure rotation, in front
    whatever the sign of t)."""
    yaw, t = np.atleast_1d(yaw), np.atleast_2d(t)
    r = np.abs(epipolar_residuals(yaw, t, a, b)) / pix
    la, lb = depths(yaw, t, a, b)
    far = _norm(_cross(a[None], _rotate(yaw, b))) / pix < 1.0
    return r, ~far & (la > 0) & (lb > 0), ~far & (la < 0) & (lb < 0), far


def known_yaw_terms(a, Rb, m, T, pix: float, ab=None, far=None):
    """Epipolar residuals (C, M) in pixels of C unit baselines T (C, 3) at one known yaw, and
    masks: in front of both cameras (C, M), no parallax (M,) (as ``_epipolar_terms``), from
    matrix products: with m = R b x a (M, 3), a . (t x R b) = t . m, |t x v|^2 = 1 - (t . v)^2
    for unit vectors, and the depths of ``depths``. a, Rb: (M, 3) unit bearings of A and of B
    turned into A's level frame; ab = a . Rb (M,) and the no-parallax mask (M,) when known."""
    num, at, bt = T @ m.T, T @ a.T, T @ Rb.T
    ab = _dot(a, Rb) if ab is None else ab
    # the depths' signs: their common divisor max(1 - ab^2, 1e-12) is positive
    front = (at - ab * bt > 0) & (ab * at - bt > 0)
    # r = |num| / sqrt(max(0.5 (2 - at^2 - bt^2), 1e-12)) / pix, in place
    q = np.subtract(2.0, np.multiply(at, at, out=at), out=at)
    q -= np.multiply(bt, bt, out=bt)
    q *= 0.5
    q = np.sqrt(np.maximum(q, 1e-12, out=q), out=q)
    r = np.abs(num, out=num)
    r /= q
    r /= pix
    return r, front, (_norm(m) / pix < 1.0) if far is None else far
