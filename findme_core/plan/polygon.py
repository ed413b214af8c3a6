"""The room's floor polygon from its wall lines and the free floor the photos saw, all in the
room frame.

Frames and units: (x, z) floor points of the room frame (level frame of the session's first
photo; metres). A wall line is a unit normal n (2,) and offset d with n . p = d (``walls``).

1. Free floor (``free_space``): every scan sample of every placed photo is a ray from its
   camera; the floor is free along it up to the first wall line it crosses within the
   wall's extent (``wall_kinds.crossing``): through furniture in front of the wall (the sample
   stopped short of it) and not past a door or an opening in it (the sample went beyond).
   A ray that crosses no wall keeps what the photo saw (its range; nothing for no floor).
2. Cell complex (as in floor-plan reconstruction from scans): the wall lines cut the plane
   into convex cells; a cell is floor when most of it is free floor. The outline of the
   floor cells around the cameras, each edge on its line, is the polygon; its vertices are
   intersections of consecutive lines, exact up to the lines themselves.
3. Each polygon edge is a wall when it lies on a wall line whose extent covers most of it,
   else "missing": the floor ends there only because nothing was seen beyond (partial
   sessions).

Pure numpy + OpenCV rasterisation; no I/O.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from findme_core.errors import GeometryError
from findme_core.geometry import ties
from findme_core.plan import wall_kinds, walls
from findme_core.single.search import SegKind


@dataclass(frozen=True)
class PolygonParams:
    """Free floor and cell voting.

    Attributes:
        res_m: raster resolution of the free floor.
        floor_share: a cell with at least this share free is floor.
        seen_share: an edge with at least this share of its length within its wall line's
            extent is a wall.
        detail_m: dents and spurs of the floor thinner than this are smoothed away, and
            jogs shorter than this between near-parallel edges removed.
        max_range_m: rays are cut at this distance from their camera.
        clutter_m: a ray is carried on to a wall at most this far past what it saw.
    """

    res_m: float = 0.02
    floor_share: float = 0.5
    seen_share: float = 0.5
    detail_m: float = 0.3
    max_range_m: float = 8.0
    clutter_m: float = 2.5


@dataclass(frozen=True)
class Lines:
    """The wall lines an outline is drawn on: normals (K, 2), offsets (K,), extents (K, 2)
    along u = (n_z, -n_x) (``walls.WallLines``)."""

    normals: np.ndarray
    offsets: np.ndarray
    extent: np.ndarray

    @classmethod
    def of(cls, wl: "walls.WallLines") -> "Lines":
        """The "wall" lines of ``wl``."""
        k = wl.walls
        return cls(wl.normals[k], wl.offsets[k], wl.extent[k])


@dataclass(frozen=True)
class Outline:
    """The floor polygon: vertices (V, 2) counter-clockwise seen from above (positive
    shoelace area in (x, z)); edge k runs from vertex k to k + 1 on line ``line[k]`` (-1: on
    no wall line) and ``seen[k]`` tells whether it is a seen wall."""

    vertices: np.ndarray
    line: np.ndarray
    seen: np.ndarray
    lines: Lines


def area(P) -> float:
    """Signed shoelace area of (V, 2) vertices (> 0 counter-clockwise in (x, z)); 0 for fewer
    than 3 (no outline: an empty list too)."""
    P = np.asarray(P, float).reshape(-1, 2)
    if len(P) < 3:
        return 0.0
    Q = np.roll(P, -1, axis=0)
    return 0.5 * float(np.sum(P[:, 0] * Q[:, 1] - Q[:, 0] * P[:, 1]))


def free_space(layouts, poses, lines: Lines, params: PolygonParams = PolygonParams()) -> list:
    """Polygons (F, 2) of free floor, one per run of rays of a photo (camera first, then the
    rays' ends in azimuth order), room frame (see the module docstring)."""
    out = []
    for L, p in zip(layouts, np.asarray(poses, float).reshape(-1, 3)):
        if L is None or not np.isfinite(p[0]) or len(L.azimuth) < 2:
            continue
        az = L.azimuth + p[2]
        d = np.column_stack([np.sin(az), np.cos(az)])
        c = np.broadcast_to(p[:2], d.shape)
        R = params.max_range_m
        seen = np.where(L.kind == SegKind.NONE, 0.0, np.minimum(L.range, R))
        if len(lines.normals):
            ok, t = wall_kinds.crossing(c, c + R * d, lines.normals, lines.offsets, lines.extent)
            t_wall = np.where(ok.any(1), np.nanmin(np.where(ok, t, np.inf), axis=1) * R, np.inf)
        else:
            t_wall = np.full(len(az), np.inf)
        reach = np.isfinite(t_wall) & (t_wall <= seen + params.clutter_m)
        r = np.where(reach, t_wall, seen)
        ends = p[:2] + r[:, None] * d
        run = []
        for k in range(len(r) + 1):     # split where nothing was seen
            if k < len(r) and r[k] > 1e-6:
                run.append(ends[k])
            elif len(run) >= 2:
                out.append(np.vstack([p[None, :2], run]))
                run = []
            else:
                run = []
    return out


def outline(lines: Lines, floor_fans, params: PolygonParams = PolygonParams(),
            anchor=(0.0, 0.0)) -> Outline:
    """The floor polygon from wall lines and the seen floor.

    Args:
        lines: the wall lines.
        floor_fans: list of (F, 2) polygons of free floor (``free_space``; room frame).
        anchor: (2,) a point known to be on the floor (a camera position): the polygon is
            the floor component that contains it (or the largest one).

    Raises:
        GeometryError: no floor was seen at all.
    """
    fans = [np.asarray(f, float).reshape(-1, 2) for f in floor_fans if len(f) >= 3]
    if not fans:
        raise GeometryError("no floor was seen in any photo: there is no outline to draw")
    allp = np.concatenate(fans)
    lo, hi = allp.min(0) - 0.5, allp.max(0) + 0.5
    res = max(params.res_m, float((hi - lo).max()) / 1500.0)
    shape = (int(np.ceil((hi[1] - lo[1]) / res)) + 1, int(np.ceil((hi[0] - lo[0]) / res)) + 1)
    floor = np.zeros(shape, np.uint8)
    for f in fans:
        cv2.fillPoly(floor, [np.round((f - lo) / res * 16).astype(np.int32)], 1, cv2.LINE_8, 4)
    zz, xx = np.mgrid[0:shape[0], 0:shape[1]]
    P = np.stack([lo[0] + xx * res, lo[1] + zz * res], -1)
    cell = np.zeros(shape, np.int64)
    for k in range(len(lines.normals)):
        cell = cell * 2 + (P @ lines.normals[k] > lines.offsets[k])
    _, inv = np.unique(cell.ravel(), return_inverse=True)
    share = np.bincount(inv, weights=floor.ravel()) / np.bincount(inv)
    mask = (share[inv] >= params.floor_share).reshape(shape).astype(np.uint8)
    r = max(1, int(round(params.detail_m / res / 2)))   # dents and spurs thinner than detail_m
    ker = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * r + 1, 2 * r + 1))
    mask = cv2.morphologyEx(cv2.morphologyEx(mask, cv2.MORPH_CLOSE, ker), cv2.MORPH_OPEN, ker)
    # back to whole cells (their edges lie on the lines): a cell is floor when most of it is
    share = np.bincount(inv, weights=mask.ravel()) / np.bincount(inv)
    mask = (share[inv] >= 0.5).reshape(shape).astype(np.uint8)
    n, comp = cv2.connectedComponents(mask, connectivity=4)
    if n <= 1:
        raise GeometryError("no cell between the walls was seen as floor: there is no outline")
    a = np.clip(np.round((np.asarray(anchor, float) - lo) / res).astype(int), 0,
                np.array(shape[::-1]) - 1)
    c = comp[a[1], a[0]]
    if c == 0:
        c = 1 + int(np.argmax(np.bincount(comp.ravel())[1:]))
    contours, _ = cv2.findContours((comp == c).astype(np.uint8), cv2.RETR_EXTERNAL,
                                   cv2.CHAIN_APPROX_NONE)
    cnt = max(contours, key=cv2.contourArea)
    raw = cv2.approxPolyDP(cnt, 2.0, True).reshape(-1, 2).astype(float) * res + lo
    return _snap_outline(raw, lines, res, params)


def _snap_outline(raw, lines: Lines, res: float, params: PolygonParams) -> Outline:
    """Each raw edge onto the line it lies on; vertices at the intersections."""
    if area(raw) < 0:
        raw = raw[::-1]
    V = len(raw)
    on = np.full(V, -1)
    for k in range(V):
        p, q = raw[k], raw[(k + 1) % V]
        if len(lines.normals) == 0:
            break
        dist = np.abs(np.stack([p, q, (p + q) / 2]) @ lines.normals.T - lines.offsets)
        e = (q - p) / max(np.linalg.norm(q - p), 1e-12)
        par = np.abs(lines.normals @ e) < np.sin(np.radians(10))
        err = np.where(par, dist.max(0), np.inf)
        if err.min() < 4 * res:
            on[k] = int(np.argmin(err))
    # merge consecutive edges on one line
    keep = [k for k in range(V) if not (on[k] >= 0 and on[k] == on[k - 1])]
    if len(keep) < 3:
        keep = list(range(V))
    starts = [raw[k] for k in keep]
    line = np.array([on[k] for k in keep])
    verts = []
    for i, k in enumerate(keep):
        a, b = line[i - 1], line[i]
        v = starts[i]
        if a >= 0 and b >= 0 and a != b:
            A = np.array([lines.normals[a], lines.normals[b]])
            if abs(np.linalg.det(A)) > 1e-3:
                x = np.linalg.solve(A, [lines.offsets[a], lines.offsets[b]])
                v = x if np.linalg.norm(x - starts[i]) < 0.5 else v
            elif np.all(np.isfinite(v)):   # parallel: drop v onto line b
                v = v - (lines.normals[b] @ v - lines.offsets[b]) * lines.normals[b]
        elif b >= 0:
            v = v - (lines.normals[b] @ v - lines.offsets[b]) * lines.normals[b]
        elif a >= 0:
            v = v - (lines.normals[a] @ v - lines.offsets[a]) * lines.normals[a]
        verts.append(v)
    verts = np.array(verts)
    return _simplify(Outline(verts, line, _seen(verts, line, lines, params), lines), params)


def _edge_lines(o: Outline):
    """(V, 2) normals and (V,) offsets of each edge's line (its wall line, or the line
    through its end points)."""
    V = o.vertices
    N, D = np.zeros((len(V), 2)), np.zeros(len(V))
    for k in range(len(V)):
        if o.line[k] >= 0:
            N[k], D[k] = o.lines.normals[o.line[k]], o.lines.offsets[o.line[k]]
        else:
            e = V[(k + 1) % len(V)] - V[k]
            n = np.array([-e[1], e[0]]) / max(np.linalg.norm(e), 1e-12)
            N[k], D[k] = n, float(n @ V[k])
    return N, D


def _simplify(o: Outline, params: PolygonParams) -> Outline:
    """Jogs (an edge shorter than ``detail_m`` between two near-parallel edges) removed: the
    longer neighbour's line goes on; vertices re-intersected."""
    verts, line, seen = o.vertices, o.line.copy(), o.seen.copy()
    while len(verts) > 4:
        N, D = _edge_lines(Outline(verts, line, seen, o.lines))
        V = len(verts)
        lens = np.linalg.norm(np.roll(verts, -1, axis=0) - verts, axis=1)
        jog = None
        for k in ties.order(lens, descending=False):   # equal lengths: in vertex order
            if lens[k] >= params.detail_m:
                break
            a, b = (k - 1) % V, (k + 1) % V
            if abs(N[a] @ N[b]) > np.cos(np.radians(15)):
                jog = k
                break
        if jog is None:
            break
        a, b = (jog - 1) % V, (jog + 1) % V
        keep_e, drop_e = (a, b) if lens[a] >= lens[b] else (b, a)
        drop = {jog, drop_e}
        idx = [k for k in range(V) if k not in drop]
        # the kept edge takes over the dropped neighbour's place in the cycle
        line = np.array([line[k] for k in idx])
        seen = np.array([seen[k] for k in idx])
        Nn, Dn = N[idx], D[idx]
        new = []
        for i in range(len(idx)):
            A = np.array([Nn[i - 1], Nn[i]])
            if abs(np.linalg.det(A)) > 1e-3:
                new.append(np.linalg.solve(A, [Dn[i - 1], Dn[i]]))
            else:
                new.append(verts[idx[i]])
        verts = np.array(new)
        if area(verts) <= 0:
            return o
    return Outline(verts, line, seen, o.lines)


def _seen(verts, line, lines: Lines, params: PolygonParams) -> np.ndarray:
    """(V,) whether each edge lies on a wall line whose extent covers ``seen_share`` of it."""
    V = len(verts)
    out = np.zeros(V, bool)
    for k in range(V):
        if line[k] < 0:
            continue
        u = walls.direction(lines.normals[line[k]])
        a, b = sorted((float(verts[k] @ u), float(verts[(k + 1) % V] @ u)))
        lo, hi = lines.extent[line[k]]
        out[k] = max(0.0, min(b, hi) - max(a, lo)) >= params.seen_share * max(b - a, 1e-9)
    return out
