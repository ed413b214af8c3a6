"""How far the 3D points of a scene may be off: the 1-sigma terms of ``scene.Scene``.

A located point's 1-sigma radius (metres) is the root sum of squares of four parts:

* boundary: the chosen boundary off by ``boundary_sigma_px`` (linearised: the scene rebuilt
  under the boundary moved by one pixel, the displacement scaled up), moved down or sideways,
  whichever moves the point more: a steep boundary (the base of a wall running away from the
  camera) moved down slides along itself, so only the sideways move shows its error;
* height: the camera height off by its sigma (every point scales with it);
* pixel: the tap off by one pixel in u and in v;
* gravity: gravity's tilt off along each principal axis of its covariance (central
  differences of the scene rebuilt under gravity tilted by +-``TILT_STEP``).

Frames and units: pixels (u, v); points in the camera's level frame (y down along gravity)
inside, camera frame for the gravity displacements; metres, radians.
"""

from __future__ import annotations

import cv2
import numpy as np

from findme_core.errors import GeometryError, HypothesisError

#: 1-sigma of a chosen boundary's position on real photos, pixels of the ~640 px working
#: size (the hypotheses' resolution). Fitted on an earlier dev run so that 68 % of wall and
#: non-floor points lay within their 1-sigma; a rule that shrinks it until the wrong
#: boundaries' points lie beyond 3 sigma (19.9 px on 2026-11-30: 0.81 against 0.88 within 3).
#: tools/calibrate_sigma.py now chooses it by the rule every sigma constant is
#: (``sigma_coverage.rule_key``: coverage within 1 and 3 sigma nearest the goal, 0.60-0.80
#: and >= 0.97, then a Gaussian's): on 2026-12-02, with the kitchen's level photos refused
#: (``flat``), 36.5 px on all dev rooms (0.834 / 0.897 / 0.932 within 1 / 2 / 3 sigma), 34.4-
#: 37.9 with one room left out but room06, the kitchen (14.6); left out 0.803 / 0.858 /
#: 0.895. Kept at 34 (0.829 / 0.893 / 0.928), within 10 % of the rule's value. The rule
#: before, nearest a Gaussian alone, had gone to 13.2 px that day (0.72 / 0.87), where every
#: row's points and distances lose within 3 sigma (ZInD wall points 0.93 -> 0.86, TUM's
#: cabinet faces 0.91 -> 0.87, distances 0.99 -> 0.96 and 0.92 -> 0.88).
BOUNDARY_SIGMA_WORK_PX = 34.0
WORK_SIZE_PX = 640


def boundary_sigma_px(width: int, height: int) -> float:
    """``BOUNDARY_SIGMA_WORK_PX`` in pixels of a ``width`` x ``height`` photo."""
    return BOUNDARY_SIGMA_WORK_PX * max(width, height) / WORK_SIZE_PX


#: tilt step of the numerical derivative of the gravity part, radians
TILT_STEP = 1e-3


def _kept(scene, pieces, r, surface, edges, cam):
    """(N,) ray parameters of the points under ``pieces`` (and camera ``cam``), each kept on
    its surface: a floor point on the floor (the boundary does not move it), a point on a top
    on its top (its front edge's pixel in ``edges`` fixed), a wall point on its wall."""
    t, _, _ = scene._solve(pieces, r)
    t = np.where(surface == 1, np.where(r[:, 1] > 0, scene.height / np.maximum(r[:, 1], 1e-300),
                                        np.nan), t)
    top = surface == 3
    if top.any():
        t[top] = scene._top_t(pieces, r[top], cam.rays_level(edges[top]))
    return t


def point_sigmas(scene, px: np.ndarray, rays: np.ndarray, P: np.ndarray,
                 surface: np.ndarray, edges: np.ndarray | None = None) -> tuple[dict, np.ndarray]:
    """The sigma parts of located points.

    Args:
        scene: the ``scene.Scene``.
        px: (N, 2) finite pixels; rays: (N, 3) their level rays; P: (N, 3) their level-frame
            points (NaN where none); surface: (N,) 1 floor, 2 wall, 3 top, 0 none.
        edges: (N, 2) the pixel of each top point's front edge (``tops``; NaN elsewhere).
    Returns:
        ({"height", "boundary", "pixel", "gravity"}: (N,) metres (inf where undefined;
         "pixel": the tap off by one pixel, and a top's front edge off by one row),
         (N, 2, 3) camera-frame displacement of each point for a 1-sigma tilt of gravity
         along each principal axis of ``scene.gravity_cov``).
    """
    cam = scene.camera
    edges = np.full(px.shape, np.nan) if edges is None else edges

    def moved(pieces, r, e=edges):
        d = np.linalg.norm(_kept(scene, pieces, r, surface, e, cam)[:, None] * r - P, axis=1)
        return np.where(np.isfinite(d), d, np.inf)

    shift = scene._shift_px
    top = surface == 3   # a top's edge off by one row (tops only: no work on other points)
    edge = np.zeros(len(px))
    if top.any():
        edge[top] = moved(scene._pieces, rays, edges + (0.0, 1.0))[top]
    parts = {"height": np.linalg.norm(P, axis=1) * scene.height_sigma / scene.height,
             "boundary": np.maximum(moved(scene._pieces_shifted, rays),
                                    moved(scene._pieces_sideways, rays)) * (
                 scene.boundary_sigma_px / shift if shift > 0 else 0.0),
             "pixel": np.sqrt(moved(scene._pieces, cam.rays_level(px + (1.0, 0.0))) ** 2
                              + moved(scene._pieces, cam.rays_level(px + (0.0, 1.0))) ** 2
                              + edge ** 2)}
    jac = gravity_displacements(scene, px, P, surface, edges)
    parts["gravity"] = np.sqrt((jac ** 2).sum((1, 2)))
    return parts, jac


def tilted_gravity(camera, direction, angle: float) -> np.ndarray:
    """(3,) ``camera``'s gravity (camera frame) tilted by ``angle`` radians along ``direction``
    = (e_p, e_r), weights of a tilt about the level frame's x axis (pitch) and z axis (roll),
    as a gravity covariance's principal axes are given: turned about e_p x - e_r z, so that
    dg = e_p z + e_r x (level axes x, z in camera coordinates)."""
    R = camera.R_level_from_cam
    e_p, e_r = direction
    w = angle * (e_p * R[0] - e_r * R[2])
    Rw, _ = cv2.Rodrigues(np.asarray(w, float).reshape(3, 1))
    return Rw @ camera.gravity


def gravity_displacements(scene, px: np.ndarray, P: np.ndarray, surface: np.ndarray,
                          edges: np.ndarray | None = None) -> np.ndarray:
    """(N, 2, 3) camera-frame displacement of each point for a 1-sigma tilt of gravity
    along each principal axis of ``scene.gravity_cov`` (linearised: central differences of
    the scene rebuilt under gravity tilted by +-``TILT_STEP``; the point keeps its
    surface, a top point its front edge's pixel ``edges``). Zero when gravity is exact."""
    n = len(px)
    out = np.zeros((n, 2, 3))
    evals, evecs = np.linalg.eigh(scene.gravity_cov)
    if n == 0 or not np.any(evals > 0):
        return out
    cam = scene.camera
    edges = np.full(px.shape, np.nan) if edges is None else edges
    P_cam = P @ cam.R_level_from_cam
    for k in range(2):
        s = float(np.sqrt(max(evals[k], 0.0)))
        if s == 0.0:
            continue
        moved = []
        for sign in (1.0, -1.0):
            c2 = cam.with_gravity(tilted_gravity(cam, evecs[:, k], sign * TILT_STEP))
            try:
                pieces = scene._build(scene.polyline, c2)
            except (HypothesisError, GeometryError):
                moved.append(np.full((n, 3), np.nan))
                continue
            rays = c2.rays_level(px)
            t = _kept(scene, pieces, rays, surface, edges, c2)
            moved.append((t[:, None] * rays) @ c2.R_level_from_cam)
        d = (moved[0] - moved[1]) * (s / (2 * TILT_STEP))
        out[:, k] = np.where(np.isfinite(d), d, np.inf)
    out[~np.isfinite(P_cam).all(1)] = 0.0
    return out


def distances(points: list, height: float, height_sigma: float):
    """Distances between consecutive located points (``scene.Located``, metres) and their
    1-sigma.

    Height errors scale every point alike, so that part of a distance's sigma is
    d * height_sigma / height; a gravity tilt moves every point of the photo together, so
    its part is the change of the distance along each tilt axis (``Located.gravity_jac``);
    boundary, pixel and surface parts (a top's reading, ``tops.face_or_top``; a step's face,
    ``steps.floor_or_face``) are taken as independent.

    Returns:
        list of (distance | None, sigma | None, error | None), len(points) - 1 entries.
    """
    out = []
    for a, b in zip(points[:-1], points[1:]):
        if a.xyz is None or b.xyz is None:
            out.append((None, None, "an end point has no 3D position"))
            continue
        d = float(np.linalg.norm(b.xyz - a.xyz))
        grav = 0.0
        if a.gravity_jac is not None and b.gravity_jac is not None and d > 0:
            grav = float(np.sum(((b.gravity_jac - a.gravity_jac) @ ((b.xyz - a.xyz) / d)) ** 2))
        s = np.sqrt((d * height_sigma / height) ** 2 + grav
                    + a.sigma_parts["boundary"] ** 2 + b.sigma_parts["boundary"] ** 2
                    + a.sigma_parts["pixel"] ** 2 + b.sigma_parts["pixel"] ** 2
                    + a.sigma_parts["surface"] ** 2
                    + b.sigma_parts["surface"] ** 2)
        out.append((d, float(s), None))
    return out
