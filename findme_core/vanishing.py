"""Gravity from the image: the vertical and horizontal vanishing directions of a Manhattan
world (the paper's rooms: vertical walls meeting at right angles on a level floor).

Frames and units: pixels (u, v) with the pixel-centre origin; directions are unit 3-vectors
in the camera frame (OpenCV: x right, y down, z forward); angles in radians.

Method (``estimate_gravity``):

1. LSD segments of the photo at a ~640 px working size, merged into lines
   (``lines.detect_segments`` / ``merge_collinear``); a line's weight is its support (pixels
   of the segments merged into it). n = K^T l is the normal of its interpretation plane.
2. Search: gravity hypotheses g on a 3 deg grid over the tilt prior (pitch in
   ``pitch_range``, roll in ``roll_range``: an upright hand-held photo), each completed to a
   Manhattan frame: the horizontal directions' azimuth is the weighted mode (modulo 90 deg)
   of the other lines' horizontal directions n x g. Every line counts for the nearest of the
   frame's three vanishing points (image angle between the line and the line from its
   midpoint to the point, truncated quadratic within the inlier angle), never for a point
   on or just past its own segment (a room corner where lines meet is not a vanishing
   point). The best peaks are searched again on a 0.5 deg grid.
3. The frame R = [h1, g, h2] is refined by Gauss-Newton on the signed image angles of its
   inlier lines (weights = support); the covariance sigma^2 (J^T W J)^-1 of the rotation is
   projected on gravity's two degrees of freedom (about the level x axis = pitch, z axis =
   roll) and inflated by the model error fitted on the dev split (``sigma_scale``,
   ``sigma_floor_deg``; tools/calibrate_sigma.py).
4. Too little evidence (fewer than 4 inlier lines, no vertical line and not two horizontal
   directions, a degenerate fit) or a 1-sigma above ``max_sigma_deg``: "level" is assumed,
   with ``level_sigma_deg``, and the reason is given.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numpy as np

from .camera import Camera
from .lines import detect_segments, merge_collinear

DOWN = np.array([0.0, 1.0, 0.0])


@dataclass(frozen=True)
class GravityParams:
    work_size: int = 640
    lsd_scale: float = 0.8
    min_line_px: float = 20.0       # lines with less support are not used
    max_lines: int = 200
    coarse_lines: int = 60          # the coarse search scores the heaviest lines only
    pitch_range: tuple = (-25.0, 60.0)   # degrees; > 0 looking down
    roll_range: tuple = (-40.0, 40.0)
    inlier_deg: float = 1.5
    iterations: int = 4
    sigma_scale: float = 2.0        # model error: sigma = hypot(scale * sigma_fit, floor),
                                    # fitted by tools/calibrate_sigma.py
    sigma_floor_deg: float = 0.3
    max_sigma_deg: float = 4.0      # a worse estimate is not used: level assumed
    level_sigma_deg: float = 10.0   # 1-sigma of "level" when nothing better is known


@dataclass(frozen=True)
class GravityEstimate:
    """Gravity of one photo and how well it is known.

    Attributes:
        vector: (3,) unit gravity (down) in camera coordinates.
        cov: (2, 2) covariance of gravity's tilt, rad^2, about the level frame's x axis
            (pitch) and z axis (roll) of ``vector``.
        source: "image" (vanishing directions) or "level" (assumed).
        lines: (vertical, horizontal) inlier line counts.
        reason: why "level" was assumed, else None.
    """

    vector: np.ndarray
    cov: np.ndarray
    source: str
    lines: tuple[int, int] = (0, 0)
    reason: str | None = None

    @property
    def sigma(self) -> float:
        """RMS 1-sigma of the tilt per axis, radians."""
        return float(math.sqrt(max(np.trace(self.cov), 0.0) / 2.0))


def level_estimate(reason: str, sigma_deg: float = GravityParams.level_sigma_deg) -> GravityEstimate:
    """Level (0, 1, 0) assumed, with ``sigma_deg`` per axis."""
    s = math.radians(sigma_deg)
    return GravityEstimate(DOWN.copy(), np.eye(2) * s * s, "level", (0, 0), reason)


# ------------------------------------------------------------------------------ geometry
def _tilt_ok(D: np.ndarray, p: GravityParams) -> np.ndarray:
    """(M,) bool: direction(s) D (M, 3), y > 0, within the pitch and roll prior."""
    pitch = np.degrees(np.arcsin(np.clip(D[:, 2], -1, 1)))
    roll = np.degrees(np.arctan2(D[:, 0], D[:, 1]))
    return ((pitch >= p.pitch_range[0]) & (pitch <= p.pitch_range[1])
            & (roll >= p.roll_range[0]) & (roll <= p.roll_range[1]))


def _signed_angles(mid: np.ndarray, lines2: np.ndarray, vps: np.ndarray) -> np.ndarray:
    """(N, M) signed sine of the image angle between line i and the line from its midpoint
    to vanishing point j (homogeneous, may be at infinity). NaN where undefined."""
    lp = np.cross(mid[:, None, :], vps[None, :, :])          # (N, M, 3) line through mid and vp
    n2 = lp[..., :2]
    nn = np.linalg.norm(n2, axis=-1)
    with np.errstate(invalid="ignore", divide="ignore"):
        n2 = n2 / nn[..., None]
    a = lines2[:, None, :]
    dot = (a * n2).sum(-1)
    cross = a[..., 0] * n2[..., 1] - a[..., 1] * n2[..., 0]
    s = np.where(dot < 0, -cross, cross)
    return np.where(nn > 1e-12, s, np.nan)


def _rot(w: np.ndarray) -> np.ndarray:
    R, _ = cv2.Rodrigues(np.asarray(w, float).reshape(3, 1))
    return R


@dataclass
class _Lines:
    mid: np.ndarray      # (N, 3) homogeneous midpoints
    dir2: np.ndarray     # (N, 2) unit normals of the image lines
    n: np.ndarray        # (N, 3) unit interpretation-plane normals
    w: np.ndarray        # (N,) support, pixels
    half: np.ndarray     # (N,) half the extent, pixels

    def subset(self, sel) -> "_Lines":
        return _Lines(self.mid[sel], self.dir2[sel], self.n[sel], self.w[sel], self.half[sel])


def _too_near(L: _Lines, vps: np.ndarray) -> np.ndarray:
    """(N, M) True where vanishing point j lies on or just beyond line i's segment: the image
    of a 3D line never reaches its vanishing point, while lines meeting at a corner of the
    room do meet there (a corner is not a vanishing point)."""
    w = vps[None, :, 2]
    with np.errstate(invalid="ignore", divide="ignore"):
        d = np.hypot(vps[None, :, 0] / w - L.mid[:, None, 0], vps[None, :, 1] / w - L.mid[:, None, 1])
    return np.isfinite(d) & (d < 1.25 * L.half[:, None] + 10.0)


def _lines(image: np.ndarray, cam: Camera, p: GravityParams) -> tuple[_Lines, Camera]:
    H, W = image.shape[:2]
    s = min(1.0, p.work_size / max(H, W))
    if s < 0.95:
        small = cv2.resize(image, (round(W * s), round(H * s)), interpolation=cv2.INTER_AREA)
        c = cam.scaled(s)
        cam = Camera(c.fx, c.fy, c.cx, c.cy, small.shape[1], small.shape[0])
        image = small
    ln = merge_collinear(detect_segments(image, "lsd", lsd_scale=p.lsd_scale))
    keep = ln.support >= p.min_line_px
    ln = ln.subset(keep)
    if len(ln) > p.max_lines:
        ln = ln.subset(np.arange(p.max_lines))            # heaviest first
    mid = np.column_stack([(ln.ends[:, :2] + ln.ends[:, 2:]) / 2, np.ones(len(ln))])
    n = ln.coef @ cam.K                                   # K^T l, as rows
    n /= np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-12)
    half = ln.length / 2
    return _Lines(mid, ln.coef[:, :2].copy(), n, ln.support.astype(float), half), cam


# ------------------------------------------------------------------------------ stages
def _grid(p: GravityParams, step_deg: float, centre=None, span_deg=None) -> np.ndarray:
    """(M, 3) gravity directions on a pitch x roll grid (the prior box, or +- span around
    ``centre``'s pitch and roll)."""
    if centre is None:
        pr, rr = p.pitch_range, p.roll_range
    else:
        c_p = math.degrees(math.asin(float(np.clip(centre[2], -1, 1))))
        c_r = math.degrees(math.atan2(centre[0], centre[1]))
        pr, rr = (c_p - span_deg, c_p + span_deg), (c_r - span_deg, c_r + span_deg)
    P, Rl = np.meshgrid(np.radians(np.arange(pr[0], pr[1] + 1e-9, step_deg)),
                        np.radians(np.arange(rr[0], rr[1] + 1e-9, step_deg)), indexing="ij")
    P, Rl = P.ravel(), Rl.ravel()
    # gravity of a camera pitched by P (down) and rolled by Rl: g = (cos P sin R, cos P cos R, sin P)
    return np.column_stack([np.cos(P) * np.sin(Rl), np.cos(P) * np.cos(Rl), np.sin(P)])


def _manhattan_score(L: _Lines, K: np.ndarray, G: np.ndarray, tau_deg: float,
                     p: GravityParams) -> tuple[np.ndarray, np.ndarray]:
    """Score of each gravity hypothesis G (M, 3) as a Manhattan frame: the horizontal
    directions' azimuth is the mode (modulo 90 deg) of the other lines' horizontal
    directions n x g; then every line counts for the nearest of the three vanishing points
    (image angle within ``tau_deg``, truncated quadratic, never a point on or just past the
    line's own segment); the score is the total weighted support.
    Returns ((M,) scores, (M,) azimuths in radians)."""
    tau = math.sin(math.radians(tau_deg))
    M = len(G)
    Gv = G @ K.T
    rv = np.abs(_signed_angles(L.mid, L.dir2, Gv))                # (N, M)
    rv = np.where(np.isfinite(rv) & ~_too_near(L, Gv), rv, 1.0)
    x = np.cross(G, [0.0, 0.0, 1.0])
    x /= np.linalg.norm(x, axis=1, keepdims=True)
    z = np.cross(x, G)
    h = np.cross(L.n[:, None, :], G[None, :, :])                  # (N, M, 3)
    nh = np.linalg.norm(h, axis=-1)
    az = np.arctan2((h * x[None]).sum(-1), (h * z[None]).sum(-1))
    nb = max(4, int(round(90.0 / tau_deg)))
    b = (np.mod(az, np.pi / 2) / (np.pi / 2) * nb).astype(int) % nb
    wh = np.where((rv > 2 * tau) & (nh > 0.2), L.w[:, None], 0.0)
    hist = np.bincount((np.arange(M)[None, :] * nb + b).ravel(), wh.ravel(),
                       M * nb).reshape(M, nb)
    sm = 0.5 * hist + 0.25 * (np.roll(hist, 1, 1) + np.roll(hist, -1, 1))
    a = (np.argmax(sm, axis=1) + 0.5) * (np.pi / 2) / nb
    h1 = np.sin(a)[:, None] * x + np.cos(a)[:, None] * z
    h2 = np.cross(h1, G)
    r = np.stack([rv] + [np.where(_too_near(L, hh @ K.T), 1.0,
                                  np.abs(_signed_angles(L.mid, L.dir2, hh @ K.T)))
                         for hh in (h1, h2)])
    r = np.where(np.isfinite(r), r, 1.0)                           # (3, N, M)
    near = np.argmin(r, axis=0)
    c = L.w[None, :, None] * np.clip(1 - (r / tau) ** 2, 0, None)
    c = np.where(np.arange(3)[:, None, None] == near[None], c, 0.0)
    score = c.sum((0, 1))
    return score, a


def _search(L: _Lines, K: np.ndarray, p: GravityParams) -> tuple[np.ndarray, float] | None:
    """Best gravity by a coarse grid over the tilt prior, then finer grids around the best
    few peaks. Returns (g (3,), horizontal azimuth) or None."""
    G = _grid(p, 3.0)
    top = slice(0, p.coarse_lines)                        # heaviest lines first
    s, _ = _manhattan_score(L.subset(top), K, G, 3.0, p)
    order = np.argsort(-s)
    peaks: list[np.ndarray] = []
    for i in order:                                   # up to 4 peaks 6 deg apart
        if s[i] <= 0:
            break
        if all(G[i] @ q < math.cos(math.radians(6)) for q in peaks):
            peaks.append(G[i])
            if len(peaks) == 4:
                break
    best, best_s, best_a = None, -1.0, 0.0
    for q in peaks:
        for step, span, tau in ((0.5, 2.0, p.inlier_deg),):
            F = _grid(p, step, q, span)
            fs, fa = _manhattan_score(L, K, F, tau, p)
            i = int(np.argmax(fs))
            q, qs, qa = F[i], fs[i], fa[i]
        if qs > best_s:
            best, best_s, best_a = q, qs, qa
    return None if best is None else (best, best_a)


def _refine(L: _Lines, K: np.ndarray, R: np.ndarray, use_h: bool, p: GravityParams):
    """Gauss-Newton on the frame R (columns h1, g, h2). Without horizontal directions only
    the two rotations that move g are estimated. Returns (R, covariance (3, 3) of the
    rotation vector in camera coordinates or None when degenerate, inlier masks (3, N))."""
    tau = math.sin(math.radians(p.inlier_deg))
    cols = [0, 1, 2] if use_h else [1]
    masks = np.zeros((3, len(L.w)), bool)
    cov = None
    for _ in range(p.iterations):
        r = _signed_angles(L.mid, L.dir2, R.T @ K.T)      # (N, 3): vp of each column
        ra = np.where(np.isfinite(r), np.abs(r), np.inf)
        best = np.argmin(ra, axis=1)
        masks[:] = False
        for c in cols:
            masks[c] = (best == c) & (ra[:, c] < 2 * tau)
        rows = [(c, np.flatnonzero(masks[c])) for c in cols if masks[c].any()]
        if not rows:
            return R, None, masks

        def residuals(Rm):
            v = Rm.T @ K.T
            return np.concatenate([_signed_angles(L.mid[ix], L.dir2[ix], v[c:c + 1])[:, 0]
                                   for c, ix in rows])

        B = R if use_h else R[:, [0, 2]]                  # rotation axes estimated
        e = residuals(R)
        w = np.concatenate([L.w[ix] for _, ix in rows])
        w = w / w.mean()
        J = np.zeros((len(e), B.shape[1]))
        for k in range(B.shape[1]):
            d = 1e-6 * B[:, k]
            J[:, k] = (residuals(_rot(d) @ R) - residuals(_rot(-d) @ R)) / 2e-6
        A = J.T @ (w[:, None] * J)
        if len(e) <= B.shape[1] or np.linalg.cond(A) > 1e10:
            return R, None, masks
        step = -np.linalg.solve(A, J.T @ (w * e))
        R = _rot(B @ step) @ R
        s2 = float((w * residuals(R) ** 2).sum() / (len(e) - B.shape[1]))
        cov = B @ (s2 * np.linalg.inv(A)) @ B.T
        if np.linalg.norm(step) < 1e-7:
            break
    return R, cov, masks


def estimate_gravity(image: np.ndarray, camera: Camera,
                     params: GravityParams = GravityParams()) -> GravityEstimate:
    """Gravity of a photo from its vanishing directions (see the module docstring).

    Args:
        image: (H, W, 3) uint8 BGR (or (H, W) grey), the size of ``camera``.
        camera: intrinsics of the photo (its gravity is ignored).
    Returns:
        GravityEstimate; source "level" (with the reason) when the image cannot tell.
    """
    p = params
    L, cam = _lines(image, camera, p)
    K = cam.K
    if len(L.w) < 3:
        return level_estimate(f"only {len(L.w)} straight lines in the photo: level assumed",
                              p.level_sigma_deg)
    found = _search(L, K, p)
    if found is None:
        return level_estimate("no vertical or horizontal structure within the tilt a hand-held "
                              "photo has: level assumed", p.level_sigma_deg)
    g, a = found
    x = np.cross(g, [0.0, 0.0, 1.0])
    x /= np.linalg.norm(x)
    z = np.cross(x, g)
    h1 = math.sin(a) * x + math.cos(a) * z
    R = np.column_stack([h1, g, np.cross(h1, g)])
    R, cov, masks = _refine(L, K, R, True, p)
    nv, nh = int(masks[1].sum()), int(masks[0].sum() + masks[2].sum())
    if cov is None or nv + nh < 4 or (nv == 0 and min(masks[0].sum(), masks[2].sum()) < 2):
        return level_estimate(f"too few vertical lines ({nv}) and horizontal lines ({nh}) to "
                              "tell gravity: level assumed", p.level_sigma_deg)
    g = R[:, 1] / np.linalg.norm(R[:, 1])
    if g[1] < 0:
        g = -g
    if not _tilt_ok(g[None], p)[0]:
        return level_estimate("the vertical direction found is outside the tilt of a "
                              "hand-held photo: level assumed", p.level_sigma_deg)
    # tilt covariance: dg = dw x g; its components along the level x (roll) and z (pitch)
    xl = np.cross(g, [0.0, 0.0, 1.0])
    xl /= np.linalg.norm(xl)
    zl = np.cross(xl, g)
    # dg = dw x g: its forward part (dw x g) . zl = dw . (g x zl) is the pitch change, its
    # rightward part the roll change
    A = np.array([np.cross(g, zl), np.cross(g, xl)])
    C = A @ cov @ A.T
    floor = math.radians(p.sigma_floor_deg) ** 2
    C = p.sigma_scale ** 2 * C + floor * np.eye(2)
    est = GravityEstimate(g, C, "image", (nv, nh))
    if est.sigma > math.radians(p.max_sigma_deg):
        return level_estimate(f"gravity from the image is too uncertain "
                              f"({math.degrees(est.sigma):.1f} deg): level assumed",
                              p.level_sigma_deg)
    return est
