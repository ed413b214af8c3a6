"""A point on top of something standing on the floor: a counter, a cabinet, a table, a desk.

The paper's scene has two surfaces, the floor and the walls on its boundary. A tapped point on
the top of a piece of furniture is on neither: lifted onto the face below it (a wall point,
eqs. 3-4) it comes out up to the furniture's depth too near (TUM's cabinet tops, dev split: a
median 0.19 m off, 0.70 m at the 90th percentile). A user who says "top" gets it on the top.

Geometry, in the photo's LEVEL frame (x right, y down along gravity, z forward; metres; the
floor is y = h, the camera height). The tapped pixel's ray r meets the chosen boundary's WALL
piece in its direction, the *face*: the vertical plane n . (x, z) = c (unit n). The top's
**front edge** is where that face ends: a straight image line crossing the pixel's column
below the pixel that is, in 3D, level and parallel to the face, i.e. its interpretation plane
(through the camera and the line; normal m = r1 x r2 of its ends' rays) contains the face's
horizontal direction d = (n_z, 0, -n_x): |m . d| < sin(``parallel_deg``). Lifted onto the
face (the wall point of eqs. 3-4) the edge's point in the column, ray e, lies at

    y_e = e_y c / (n . e_xz)  (> 0: below the camera),  a height H = h - y_e above the floor,

and the top is the plane y = y_e: the tapped point is its ray scaled to meet it,

    P = (y_e / r_y) r       (eq. 2, with the camera y_e above the top instead of h).

Of the lines that qualify, the one nearest below the pixel is taken: a face's other level
lines (drawers, doors, its foot) lie lower, and the top's own lines (its back edge, a seam)
lie beyond the front edge, so above the pixel when it is tapped in front of them. A pixel
tapped beyond a seam takes the seam: its top then reads high, and the point too near, by the
seam's depth times the ray's dip. A front edge the photo's lines miss lets the next level line
down be taken (a drawer's edge): the top then reads low and the point too far.

What is refused, with the reason (``answers``): a pixel the chosen boundary puts on the floor
(a free-standing cabinet is measured where the line steps round its foot, but a table on
legs, with floor seen under it, has no face on the line), no edge in
its column, a top at or above the camera, and a point that would lie farther behind its edge
than a top reaches (``max_depth_m``: a level line on a wall taken for an edge).

A pixel nobody said the surface of, which the boundary puts on a face with a top's front edge
found below it (``face_or_top``), is read on the face, as the boundary says, but it may be on
that top (or beyond it): its 1-sigma gains the distance between the two readings. Dev split,
TUM's cabinet (dataset's gravity, nothing said): the non-floor points off the vertical (the
cabinet's top) lay 0.47 / 0.66 / 0.78 within 1 / 2 / 3 sigma of the face reading with its
1-sigma alone; 0.83 / 0.89 / 0.90 with the reading's spread.

``edge_rows`` finds the edges; ``top_t`` places the points under any boundary and camera
(``uncertainty`` moves both); ``place`` does both for a ``scene.Scene``'s pixels said to be on
a top. Thresholds are round numbers, not fitted. Pure numpy; no I/O.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from findme_core.single.answers import Reason

#: pixel x line pairs tested at once (``edge_rows``): ~10 arrays of this many float64, ~20 MB
BLOCK = 1 << 18


@dataclass(frozen=True)
class TopParams:
    """What a top's front edge is (pixels; metres).

    Attributes:
        parallel_deg: the edge is parallel to the face within this (``counters``' value).
        not_vertical_deg: its interpretation plane is at least this far from vertical (a
            vertical line's is vertical).
        min_height_m: a top is at least this high (a baseboard's top edge, 0.07-0.15 m,
            is a level line on a wall).
        clearance_m: the top lies at least this far below the camera (it looks down on it).
        reach_px: a line counts in columns up to this far past its ends.
        gap_px: the edge lies at least this many rows below the tapped pixel.
        max_depth_m: a point on a top lies at most this far behind its front edge (a table
            seen across, a counter: a level line on a wall, a sill or a picture's edge,
            taken for an edge puts the point metres behind it).
    """

    parallel_deg: float = 2.5
    not_vertical_deg: float = 10.0
    min_height_m: float = 0.20
    clearance_m: float = 0.05
    reach_px: float = 3.0
    gap_px: float = 2.0
    max_depth_m: float = 1.2


def line_normals(camera, lines: np.ndarray) -> np.ndarray:
    """(L, 3) unit normals, in the level frame, of the interpretation planes of (L, 4)
    image lines [u1, v1, u2, v2] (pixels of ``camera``): m = r1 x r2 of their ends' rays."""
    ends = np.asarray(lines, float).reshape(-1, 4)
    m = np.cross(camera.rays_level(ends[:, :2]), camera.rays_level(ends[:, 2:]))
    return m / np.maximum(np.linalg.norm(m, axis=1, keepdims=True), 1e-12)


def edge_rows(camera, height: float, lines: np.ndarray, normals: np.ndarray,
              pixels: np.ndarray, face_n: np.ndarray, face_c: np.ndarray,
              params: TopParams = TopParams()) -> np.ndarray:
    """(N,) image row of the top's front edge in each pixel's column (NaN: none found).

    Args:
        camera: the photo's camera (its gravity defines the level frame).
        height: camera height above the floor, metres.
        lines: (L, 4) the photo's straight lines [u1, v1, u2, v2], pixels; normals: (L, 3)
            their ``line_normals``.
        pixels: (N, 2) tapped pixels (u, v).
        face_n: (N, 2) unit (x, z) normal of the face under each pixel; face_c: (N,) its
            offset (n . (x, z) = c, metres; either sign: the face is where c / (n . r_xz) > 0).
    """
    p = params
    px = np.asarray(pixels, float).reshape(-1, 2)
    out = np.full(len(px), np.nan)
    ends = np.asarray(lines, float).reshape(-1, 4)
    # what each line is alone: not (nearly) vertical in the image, and not a vertical in 3D
    # (a face seen at a grazing angle passes the parallel test with any line through its
    # vanishing point, a vertical edge too: a vertical's interpretation plane is vertical)
    keep = ((np.abs(ends[:, 2] - ends[:, 0]) >= 1.0)
            & (np.abs(normals[:, 1]) > math.sin(math.radians(p.not_vertical_deg))))
    ends, normals = ends[keep], normals[keep]
    if len(ends) == 0 or len(px) == 0:
        return out
    # pixels x lines in blocks of at most ``BLOCK`` pairs: a request's cost in memory is
    # bounded whatever its size (1024 pixels x 4096 lines at most on the bus)
    step = max(1, BLOCK // len(ends))
    for i in range(0, len(px), step):
        s = slice(i, i + step)
        out[s] = _nearest_edge(camera, height, ends, normals, px[s], face_n[s], face_c[s], p)
    return out


def _nearest_edge(camera, height, ends, normals, px, face_n, face_c, p: TopParams):
    """``edge_rows`` of (n, 2) pixels against (L, 4) lines that may be edges (neither steep
    nor vertical): (n,) rows, NaN where none qualifies."""
    u1, v1, u2, v2 = ends.T
    lo, hi = np.minimum(u1, u2) - p.reach_px, np.maximum(u1, u2) + p.reach_px
    u, v = px[:, :1], px[:, 1:]
    ve = v1 + (u - u1) * (v2 - v1) / (u2 - u1)                          # (n, L)
    # m . d, d = (n_z, 0, -n_x), term by term: no matrix product, whose rounding differs
    # between BLAS kernels, decides a threshold here
    md = face_n[:, 1:] * normals[None, :, 0] - face_n[:, :1] * normals[None, :, 2]
    ok = ((np.abs(md) < math.sin(math.radians(p.parallel_deg))) & (u >= lo) & (u <= hi)
          & (ve > v + p.gap_px))
    # the edge's point in the column lifted onto the face: its depth below the camera
    e = camera.rays_level(np.column_stack([np.repeat(px[:, 0], len(ends)),
                                           np.where(ok, ve, v).ravel()])).reshape(len(px), -1, 3)
    with np.errstate(divide="ignore", invalid="ignore"):
        t_e = face_c[:, None] / (face_n[:, None, 0] * e[..., 0] + face_n[:, None, 1] * e[..., 2])
        y_e = t_e * e[..., 1]
    ok &= (t_e > 0) & (y_e >= p.clearance_m) & (y_e <= height - p.min_height_m)
    best = np.where(ok, ve, np.inf).min(1, initial=np.inf)
    return np.where(np.isfinite(best), best, np.nan)


def top_t(rays: np.ndarray, edge_rays: np.ndarray, face_n: np.ndarray,
          face_c: np.ndarray) -> np.ndarray:
    """(N,) ray parameter of each top point: P = t r (module doc; NaN where the ray does not
    go down to the top or the edge is not in front of the face).

    Args:
        rays: (N, 3) level rays of the tapped pixels; edge_rays: (N, 3) of their edges.
        face_n: (N, 2) unit (x, z) normals of the faces; face_c: (N,) their offsets, metres.
    """
    with np.errstate(divide="ignore", invalid="ignore"):
        t_e = face_c / (face_n[:, 0] * edge_rays[:, 0] + face_n[:, 1] * edge_rays[:, 2])
        y_e = t_e * edge_rays[:, 1]
        t = y_e / rays[:, 1]
    return np.where((t_e > 0) & (y_e > 0) & (rays[:, 1] > 0) & np.isfinite(t), t, np.nan)


def place(scene, top, px, rays, t, surface, reason, params: TopParams = TopParams()):
    """The pixels said to be on a top, placed on it or refused with the reason.

    Args:
        scene: the ``scene.Scene`` (its pieces, lines and camera).
        top: (N,) bool, the pixels said to be on a top; px: (N, 2) pixels; rays: (N, 3)
            their level rays; t, surface, reason: (N,) each pixel's ray parameter, surface
            code and reason code as the boundary alone gives them.
    Returns:
        (t, surface, reason, (N, 2) the front edge's pixel of each point placed on a top,
        NaN elsewhere), new arrays: a top point's surface is 3; a pixel said on a top that
        the boundary puts on the floor, whose column has no edge, that would lie deeper
        behind its edge than a top is, or that lies at or above the horizon is refused
        (``Reason.TOP_ON_FLOOR``, ``NO_TOP_EDGE``, ``NO_LINES``, ``TOP_TOO_DEEP``,
        ``TOP_ABOVE``); one the boundary already refuses keeps its reason.
    """
    edges = np.full((len(px), 2), np.nan)
    k = scene._piece(scene._pieces, rays)
    n, c = scene._pieces[3][k], scene._pieces[4][k]
    face = top & (reason == 0) & (surface == 2) & (rays[:, 1] > 0)
    if scene.lines is not None and face.any():
        edges[face] = np.column_stack([px[face, 0], edge_rows(
            scene.camera, scene.height, scene.lines, line_normals(scene.camera, scene.lines),
            px[face], n[face], c[face], params)])
    found = face & np.isfinite(edges[:, 1])
    t_top = np.full(len(px), np.nan)
    t_top[found] = top_t(rays[found], scene.camera.rays_level(edges[found]), n[found], c[found])
    found &= np.isfinite(t_top)
    with np.errstate(invalid="ignore"):   # behind the face: |n . P_xz - c| (NaN: none)
        depth = np.abs((n * rays[:, [0, 2]]).sum(1) * t_top - c)
    deep = found & ~(depth <= params.max_depth_m)
    found &= ~deep
    why = np.select([rays[:, 1] <= 0, reason != 0, surface == 1,
                     np.full(len(px), scene.lines is None), deep, ~found],
                    [Reason.TOP_ABOVE, reason, Reason.TOP_ON_FLOOR, Reason.NO_LINES,
                     Reason.TOP_TOO_DEEP, Reason.NO_TOP_EDGE], 0)
    edges[~found] = np.nan
    return (np.where(found, t_top, t), np.where(found, 3, surface), np.where(top, why, reason),
            edges)


def face_or_top(scene, unsaid, px, rays, t, surface, reason,
                params: TopParams = TopParams()) -> np.ndarray:
    """(N,) metres between each point's face reading and its top reading (0: no top).

    A pixel in ``unsaid`` (N,) bool, nobody having said its surface, that the boundary puts on
    a face (``surface`` 2, ``reason`` 0, ray parameter ``t``) has a top reading where
    ``place`` (taking those pixels as said top) finds a top's front edge below it; the spread
    is |t_top - t| |r| (``rays``: (N, 3) level rays of the (N, 2) pixels ``px``): how far
    apart the two answers lie.
    """
    unsaid = np.asarray(unsaid, bool)
    out = np.zeros(len(px))
    if scene.lines is None or not unsaid.any():
        return out
    t_top, s_top, _, _ = place(scene, unsaid, px, rays, t, surface, reason, params)
    top = unsaid & (s_top == 3)
    out[top] = np.abs(t_top[top] - t[top]) * np.linalg.norm(rays[top], axis=1)
    return out
