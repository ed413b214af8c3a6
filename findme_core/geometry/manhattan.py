"""Manhattan frame of a photo from its lines: a vertical direction (gravity) and two
horizontal directions at right angles, searched and refined (``vanishing`` decides whether
the result can be used).

Frames and units: pixels (u, v) with the pixel-centre origin; directions are unit 3-vectors
in the camera frame (OpenCV: x right, y down, z forward); angles in radians unless named
``_deg``. A frame is R = [h1, g, h2] (columns: the first horizontal direction, gravity, the
second horizontal direction).

A line agrees with a vanishing point v (homogeneous, K d for a direction d) when it points
at it: the residual is the signed sine of the image angle between the line and the line
from its midpoint to v. Every residual of M points for N lines is a handful of (N, M) array
operations (no (N, M, 3) temporaries), so a grid of a thousand frames costs ~1 ms.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numpy as np


@dataclass
class LineSet:
    """Lines of one photo for the vanishing-point search.

    Attributes:
        mid: (N, 2) midpoints, pixels.
        normal: (N, 2) unit normals (a, b) of the image lines.
        n: (N, 3) unit normals of their interpretation planes (K^T l), camera frame.
        w: (N,) weights: support in pixels.
        half: (N,) half the extent, pixels.
        vertical_only: (N,) True for lines that may only be vertical (lines lying in the
            floor region are horizontal in unknown directions: rugs, seams, light), or None.
    """

    mid: np.ndarray
    normal: np.ndarray
    n: np.ndarray
    w: np.ndarray
    half: np.ndarray
    vertical_only: np.ndarray | None = None

    def __len__(self) -> int:
        return len(self.w)

    def subset(self, sel) -> "LineSet":
        vo = None if self.vertical_only is None else self.vertical_only[sel]
        return LineSet(self.mid[sel], self.normal[sel], self.n[sel], self.w[sel],
                       self.half[sel], vo)

    def only_vertical(self, mask: np.ndarray) -> "LineSet":
        """The same lines, those of ``mask`` (N,) allowed to be vertical only."""
        return LineSet(self.mid, self.normal, self.n, self.w, self.half, np.asarray(mask, bool))

    def horizontal_mask(self, r: np.ndarray) -> np.ndarray:
        """``r`` (N, M) residuals to horizontal points, 1.0 for vertical-only lines."""
        return r if self.vertical_only is None else np.where(self.vertical_only[:, None], 1.0, r)


def residuals(L: LineSet, V: np.ndarray, signed: bool = False) -> np.ndarray:
    """(N, M) sine of the image angle between line i and the line from its midpoint to
    vanishing point j of V (M, 3) (homogeneous pixels, may be at infinity): absolute, or
    signed by the line's own direction (``signed``). 1.0 where undefined and where the
    point lies on or just beyond the line's own segment (the image of a 3D line never
    reaches its vanishing point, while lines meeting at a room corner meet there: a corner
    is not a vanishing point)."""
    mx, my = L.mid[:, :1], L.mid[:, 1:]
    vx, vy, vw = V[None, :, 0], V[None, :, 1], V[None, :, 2]
    qx, qy = vx - mx * vw, vy - my * vw                     # (N, M): midpoint -> point
    ax, ay = L.normal[:, :1], L.normal[:, 1:]
    q2 = qx * qx + qy * qy
    num = ax * qx + ay * qy
    reach = (1.25 * L.half[:, None] + 10.0) * np.abs(vw)
    with np.errstate(invalid="ignore", divide="ignore"):
        s = num / np.sqrt(q2)
    if signed:
        s = np.where(ay * qx - ax * qy < 0, -s, s)
    else:
        s = np.abs(s)
    return np.where((q2 > 1e-18) & (q2 >= reach * reach), s, 1.0)


def _sq_residuals(mid, normal, reach, V) -> np.ndarray:
    """(N, M) squared ``residuals`` (unsigned) in float32, for scoring many frames: mid,
    normal (N, 2) and reach (N,) (1.25 half-extent + 10 px) float32, V (M, 3)."""
    V = V.astype(np.float32)
    vx, vy, vw = V[None, :, 0], V[None, :, 1], V[None, :, 2]
    qx = vx - mid[:, :1] * vw
    qy = vy - mid[:, 1:] * vw
    q2 = qx * qx + qy * qy
    num = normal[:, :1] * qx
    num += normal[:, 1:] * qy
    rw = reach[:, None] * vw
    with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
        s2 = num * num / q2
    return np.where((q2 > 1e-18) & (q2 >= rw * rw), s2, np.float32(1.0))


def tilt_grid(pitch_deg: tuple, roll_deg: tuple, step_deg: float) -> np.ndarray:
    """(M, 3) gravity directions on a pitch x roll grid (degrees; pitch > 0 looking down,
    roll > 0 right side lower): g = (cos P sin R, cos P cos R, sin P)."""
    P, Rl = np.meshgrid(np.radians(np.arange(pitch_deg[0], pitch_deg[1] + 1e-9, step_deg)),
                        np.radians(np.arange(roll_deg[0], roll_deg[1] + 1e-9, step_deg)),
                        indexing="ij")
    P, Rl = P.ravel(), Rl.ravel()
    return np.column_stack([np.cos(P) * np.sin(Rl), np.cos(P) * np.cos(Rl), np.sin(P)])


def pitch_roll_deg(g: np.ndarray) -> tuple[float, float]:
    """(pitch, roll) in degrees of a unit gravity (3,)."""
    return (math.degrees(math.asin(float(np.clip(g[2], -1, 1)))),
            math.degrees(math.atan2(g[0], g[1])))


def gravity_of(pitch_deg: float, roll_deg: float) -> np.ndarray:
    """(3,) unit gravity of a tilt, the inverse of ``pitch_roll_deg``."""
    P, R = math.radians(pitch_deg), math.radians(roll_deg)
    return np.array([math.cos(P) * math.sin(R), math.cos(P) * math.cos(R), math.sin(P)])


def level_axes(G: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(x, z) of the level frames of gravities G (M, 3): x = right, z = forward, both
    horizontal (z is the optical axis projected)."""
    x = np.cross(G, [0.0, 0.0, 1.0])
    x /= np.linalg.norm(x, axis=1, keepdims=True)
    return x, np.cross(x, G)


def score_frames(L: LineSet, K: np.ndarray, G: np.ndarray,
                 tau_deg: float) -> tuple[np.ndarray, np.ndarray]:
    """Score of each gravity G (M, 3) as a Manhattan frame.

    The horizontal directions' azimuth is the weighted mode (modulo 90 deg, bins of
    ``tau_deg``) of the horizontal directions n x g of the lines that are not vertical;
    then each line counts for the nearest of the frame's three vanishing points, truncated
    quadratic within ``tau_deg``: score = sum_i w_i max(0, 1 - (r_i / tau)^2).

    Returns:
        ((M,) scores, (M,) azimuths of h1 from the level z axis towards x, radians).
    """
    tau = math.sin(math.radians(tau_deg))
    M = len(G)
    mid, normal = L.mid.astype(np.float32), L.normal.astype(np.float32)
    reach = (1.25 * L.half + 10.0).astype(np.float32)
    rv = _sq_residuals(mid, normal, reach, G @ K.T)             # (N, M) vertical, squared
    x, z = level_axes(G)
    n32 = L.n.astype(np.float32)
    hx = n32 @ np.cross(G, x).T.astype(np.float32)              # (n x g) . x
    hz = n32 @ np.cross(G, z).T.astype(np.float32)              # (n x g) . z
    nb = max(4, int(round(90.0 / tau_deg)))
    az = np.arctan2(hx, hz)
    b = (np.mod(az, np.float32(np.pi / 2)) * np.float32(nb / (np.pi / 2))).astype(np.int64) % nb
    hor = (rv > 4 * tau * tau) & (hx * hx + hz * hz > 0.04)
    if L.vertical_only is not None:
        hor &= ~L.vertical_only[:, None]
    wh = np.where(hor, L.w[:, None], 0.0)
    hist = np.bincount((b + np.arange(M)[None, :] * nb).ravel(), wh.ravel(),
                       M * nb).reshape(M, nb)
    sm = 0.5 * hist + 0.25 * (np.roll(hist, 1, 1) + np.roll(hist, -1, 1))
    a = (np.argmax(sm, axis=1) + 0.5) * (np.pi / 2) / nb
    h1 = np.sin(a)[:, None] * x + np.cos(a)[:, None] * z
    r2 = np.minimum(rv, L.horizontal_mask(np.minimum(
        _sq_residuals(mid, normal, reach, h1 @ K.T),
        _sq_residuals(mid, normal, reach, np.cross(h1, G) @ K.T))))
    score = L.w @ np.clip(1.0 - r2 * np.float32(1.0 / (tau * tau)), 0.0, None)
    return score, a


def frame_of(g: np.ndarray, az: float) -> np.ndarray:
    """(3, 3) frame [h1, g, h2] of gravity g with h1 at azimuth ``az`` (radians)."""
    x, z = level_axes(g[None])
    h1 = math.sin(az) * x[0] + math.cos(az) * z[0]
    return np.column_stack([h1, g, np.cross(h1, g)])


def search(L: LineSet, K: np.ndarray, pitch_deg: tuple, roll_deg: tuple, coarse_lines: int,
           inlier_deg: float, peaks: int = 4, coarse_deg: float = 3.0, fine_deg: float = 0.5,
           span_deg: float = 2.0, fine_lines: int = 100, best: int = 1,
           ratio: float = 0.0) -> list[np.ndarray]:
    """Best frame: a ``coarse_deg`` grid over the tilt prior (pitch, roll in degrees;
    heaviest ``coarse_lines`` lines, ``coarse_deg`` inlier angle), then a ``fine_deg`` grid
    +-``span_deg`` around the best ``peaks`` peaks at least ``coarse_deg`` apart (heaviest
    ``fine_lines`` lines, ``inlier_deg``). Returns R (3, 3) or None."""
    G = tilt_grid(pitch_deg, roll_deg, coarse_deg)
    s, _ = score_frames(L.subset(slice(0, coarse_lines)), K, G, coarse_deg)
    tops: list[np.ndarray] = []
    cos_sep = math.cos(math.radians(coarse_deg))
    for i in np.argsort(-s):
        if s[i] <= 0 or len(tops) == peaks:
            break
        if all(G[i] @ q < cos_sep for q in tops):
            tops.append(G[i])
    if not tops:
        return []
    Lf = L.subset(slice(0, fine_lines))
    F = np.concatenate([tilt_grid(*((c - span_deg, c + span_deg) for c in pitch_roll_deg(q)),
                                  fine_deg) for q in tops])
    fs, fa = score_frames(Lf, K, F, inlier_deg)
    out: list[np.ndarray] = []
    order = np.argsort(-fs)
    for i in order:
        if len(out) == best or fs[i] <= 0 or (out and fs[i] < ratio * fs[order[0]]):
            break
        if all(F[i] @ R[:, 1] < cos_sep for R in out):
            out.append(frame_of(F[i], float(fa[i])))
    return out


def _jacobian(mid: np.ndarray, normal: np.ndarray, K: np.ndarray,
              D: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Signed residuals (P,) of P lines (midpoints, unit normals (P, 2)) for their own
    directions D (P, 3), and their derivatives (P, 3) for a small rotation w of the frame
    (d -> d + w x d)."""
    V = D @ K.T
    qx, qy = V[:, 0] - mid[:, 0] * V[:, 2], V[:, 1] - mid[:, 1] * V[:, 2]
    ax, ay = normal[:, 0], normal[:, 1]
    sign = np.where(ay * qx - ax * qy < 0, -1.0, 1.0)
    q2 = np.maximum(qx * qx + qy * qy, 1e-300)
    qn = np.sqrt(q2)
    num = ax * qx + ay * qy
    e = sign * num / qn
    # de/dq = sign (a / |q| - (a . q) q / |q|^3); dq/dv = [[1, 0, -mx], [0, 1, -my]]
    gx = sign * (ax / qn - num * qx / (q2 * qn))
    gy = sign * (ay / qn - num * qy / (q2 * qn))
    dv = np.column_stack([gx, gy, -(gx * mid[:, 0] + gy * mid[:, 1])])
    # dv/dw = -K [d]x, so de/dw = -(K^T dv)^T [d]x = -((K^T dv) x d)^T
    return e, -np.cross(dv @ K, D)


def refine(L: LineSet, K: np.ndarray, R: np.ndarray, inlier_deg: float, iterations: int = 4,
           min_sigma_deg: float = 0.0):
    """Gauss-Newton on the frame R (columns h1, g, h2): each line is an inlier of the
    nearest of the three vanishing points within 2 ``inlier_deg``; residuals are weighted
    by support.

    Returns:
        (R, covariance (3, 3) of the rotation vector in camera coordinates (sigma^2
        (J^T W J)^-1, sigma^2 the weighted residual variance, at least ``min_sigma_deg``
        squared: a few lines that happen to agree closely do not make the frame exact), or
        None when degenerate, inlier masks (3, N)).
    """
    tau = math.sin(math.radians(inlier_deg))
    masks = np.zeros((3, len(L)), bool)
    cov = None
    for _ in range(iterations):
        r = residuals(L, (K @ R).T)                               # (N, 3)
        r[:, [0, 2]] = L.horizontal_mask(r[:, [0, 2]])
        best = np.argmin(r, axis=1)
        ok = r[np.arange(len(L)), best] < 2 * tau
        masks = ok[None, :] & (best[None, :] == np.arange(3)[:, None])
        idx = np.flatnonzero(ok)
        if len(idx) <= 3:
            return R, None, masks
        mid, normal, D = L.mid[idx], L.normal[idx], R[:, best[idx]].T
        e, J = _jacobian(mid, normal, K, D)
        w = L.w[idx] / L.w[idx].mean()
        A = J.T @ (w[:, None] * J)
        if np.linalg.cond(A) > 1e10:
            return R, None, masks
        step = -np.linalg.solve(A, J.T @ (w * e))
        Rs, _ = cv2.Rodrigues(step.reshape(3, 1))
        R = Rs @ R
        e2, _ = _jacobian(mid, normal, K, R[:, best[idx]].T)
        s2 = max(float((w * e2 ** 2).sum() / (len(e) - 3)), math.sin(math.radians(min_sigma_deg)) ** 2)
        cov = s2 * np.linalg.inv(A)
        if np.linalg.norm(step) < 1e-7:
            break
    return R, cov, masks
