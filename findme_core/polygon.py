"""The room's floor polygon from walls and seen floor, all in the room frame.

Frames and units: (x, z) floor points of the room frame (level frame of the session's first
photo; metres). A wall line is a unit normal n (2,) and offset d with n . p = d.

1. Walls: observed wall base segments (from every photo, already posed) are clustered into
   lines: same direction within ``angle_deg`` and both ends within ``gap_m`` of the line;
   each line is the length-weighted total-least-squares fit of its segments.
2. Manhattan where the evidence says so: when at least ``manhattan_share`` of the wall length
   lies within ``manhattan_deg`` of two perpendicular axes, the lines near an axis are turned
   onto it (the others keep their own direction: nothing is forced).
3. Cell complex (as in floor-plan reconstruction from scans): the lines cut the plane into
   convex cells; a cell is floor when most of it was seen as floor (the union of the photos'
   floor fans). The outline of the floor cells, each edge on its line, is the polygon; its
   vertices are intersections of consecutive lines, exact up to the lines themselves.
4. Each polygon edge is a wall if enough of it was seen as a wall base, else "missing": the
   floor ends there only because nothing was seen beyond (partial sessions).

Pure numpy + OpenCV rasterisation; no I/O.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from .errors import GeometryError


@dataclass(frozen=True)
class PolygonParams:
    """Clustering, Manhattan test and cell voting.

    Attributes:
        angle_deg, gap_m: a segment joins a line within this angle and end distance.
        min_wall_m: lines with less seen length are dropped.
        max_lines: at most this many lines (longest seen first) cut the plane.
        manhattan_deg, manhattan_share: the Manhattan test (see module docstring).
        res_m: raster resolution of the floor evidence.
        floor_share: a cell with at least this share seen as floor is floor.
        seen_share: an edge with at least this share of its length seen as wall is a wall.
        detail_m: dents and spurs of the floor thinner than this are smoothed away
            (furniture bases, door reveals).
        wall_clip_m, clip_margin_m: floor seen across a line with at least ``wall_clip_m``
            seen, within its seen extent widened by ``clip_margin_m``, is beyond a wall (seen
            through a door or an opening of it) and is not this room's floor.
    """

    angle_deg: float = 8.0
    gap_m: float = 0.15
    min_wall_m: float = 0.3
    max_lines: int = 40
    manhattan_deg: float = 6.0
    manhattan_share: float = 0.8
    res_m: float = 0.02
    floor_share: float = 0.5
    seen_share: float = 0.3
    wall_clip_m: float = 0.5
    detail_m: float = 0.3
    clip_margin_m: float = 0.3


@dataclass(frozen=True)
class Lines:
    """Wall lines: normals (K, 2), offsets (K,) (n . p = d), seen length (K,) metres, and
    the observed segments (S, 2, 2) with their line index (S,) (-1: none)."""

    normals: np.ndarray
    offsets: np.ndarray
    seen_m: np.ndarray
    segments: np.ndarray
    line_of: np.ndarray
    manhattan: float | None   # axis angle (radians, [0, pi/2)) when Manhattan, else None


@dataclass(frozen=True)
class Outline:
    """The floor polygon: vertices (V, 2) counter-clockwise seen from above (positive
    shoelace area in (x, z)); edge k runs from vertex k to k + 1 on line ``line[k]`` (-1: on
    no wall line) and ``seen[k]`` tells whether it was seen as a wall."""

    vertices: np.ndarray
    line: np.ndarray
    seen: np.ndarray
    lines: Lines


def area(P) -> float:
    """Signed shoelace area of (V, 2) vertices (> 0 counter-clockwise in (x, z))."""
    P = np.asarray(P, float)
    Q = np.roll(P, -1, axis=0)
    return 0.5 * float(np.sum(P[:, 0] * Q[:, 1] - Q[:, 0] * P[:, 1]))


def _fit(segs, w):
    """Total-least-squares line (n, d) through segment end points and midpoints."""
    pts = np.concatenate([segs[:, 0], segs[:, 1], segs.mean(1)])
    ww = np.concatenate([w, w, 2 * w])
    c = (ww[:, None] * pts).sum(0) / ww.sum()
    X = (pts - c) * np.sqrt(ww)[:, None]
    _, _, vt = np.linalg.svd(X, full_matrices=False)
    n = vt[-1]
    return n, float(n @ c)


def cluster(segments, params: PolygonParams = PolygonParams()) -> Lines:
    """Wall lines from observed wall base segments (S, 2, 2) in the room frame."""
    segs = np.asarray(segments, float).reshape(-1, 2, 2)
    L = np.linalg.norm(segs[:, 1] - segs[:, 0], axis=1)
    line_of = np.full(len(segs), -1)
    lines = []   # [n, d, member indices]
    cos_t = np.cos(np.radians(params.angle_deg))
    for s in np.argsort(-L):
        if L[s] < 1e-6:
            continue
        u = (segs[s, 1] - segs[s, 0]) / L[s]
        best, best_gap = -1, params.gap_m
        for k, (n, d, _) in enumerate(lines):
            if abs(u @ np.array([n[1], -n[0]])) < cos_t:
                continue
            gap = float(np.max(np.abs(segs[s] @ n - d)))
            if gap < best_gap:
                best, best_gap = k, gap
        if best < 0:
            n = np.array([-u[1], u[0]])
            lines.append([n, float(n @ segs[s, 0]), [s]])
            line_of[s] = len(lines) - 1
        else:
            lines[best][2].append(s)
            line_of[s] = best
            m = np.array(lines[best][2])
            lines[best][0], lines[best][1] = _fit(segs[m], L[m])
    if not lines:
        return Lines(np.zeros((0, 2)), np.zeros(0), np.zeros(0), segs, line_of, None)
    N = np.array([ln[0] for ln in lines])
    D = np.array([ln[1] for ln in lines])
    seen = np.bincount(line_of[line_of >= 0], weights=L[line_of >= 0], minlength=len(lines))
    # keep the longest lines; renumber
    keep = np.flatnonzero(seen >= params.min_wall_m)
    keep = keep[np.argsort(-seen[keep])][: params.max_lines]
    remap = np.full(len(lines), -1)
    remap[keep] = np.arange(len(keep))
    N, D, seen = N[keep], D[keep], seen[keep]
    line_of = np.where(line_of >= 0, remap[np.maximum(line_of, 0)], -1)
    axis = _manhattan(N, seen, params)
    if axis is not None:
        N, D = _snap(N, D, segs, line_of, L, axis, params)
    return Lines(N, D, seen, segs, line_of, axis)


def _manhattan(N, seen, params: PolygonParams):
    """Axis angle (radians, [0, pi/2)) when the lines are Manhattan enough, else None."""
    if len(N) < 2:
        return None
    ang = np.arctan2(N[:, 1], N[:, 0])
    axis = float(np.angle(np.sum(seen * np.exp(4j * ang))) / 4.0) % (np.pi / 2)
    off = np.abs(np.angle(np.exp(4j * (ang - axis)))) / 4.0
    share = seen[off < np.radians(params.manhattan_deg)].sum() / seen.sum()
    return axis if share >= params.manhattan_share else None


def _snap(N, D, segs, line_of, L, axis, params: PolygonParams):
    """Lines within 2 x ``manhattan_deg`` of the axes turned onto them; offsets refitted."""
    N, D = N.copy(), D.copy()
    for k in range(len(N)):
        a = np.arctan2(N[k, 1], N[k, 0])
        q = axis + np.round((a - axis) / (np.pi / 2)) * (np.pi / 2)
        if abs(np.angle(np.exp(1j * (a - q)))) > np.radians(2 * params.manhattan_deg):
            continue
        N[k] = (np.cos(q), np.sin(q))
        m = line_of == k
        pts = np.concatenate([segs[m, 0], segs[m, 1]])
        w = np.concatenate([L[m], L[m]])
        D[k] = float((w * (pts @ N[k])).sum() / w.sum())
    return N, D


def outline(lines: Lines, floor_fans, params: PolygonParams = PolygonParams(),
            anchor=(0.0, 0.0)) -> Outline:
    """The floor polygon from wall lines and the seen floor.

    Args:
        lines: from ``cluster``.
        floor_fans: list of (F, 2) polygons of floor seen by the photos (room frame), each
            with the camera first and its boundary samples in azimuth order after it.
        anchor: (2,) a point known to be on the floor (a camera position): the polygon is
            the floor component that contains it (or the largest one).

    Raises:
        GeometryError: no floor was seen at all.
    """
    fans = [clip_fan(np.asarray(f, float).reshape(-1, 2), lines, params)
            for f in floor_fans if len(f) >= 3]
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


def clip_fan(fan: np.ndarray, lines: Lines, params: PolygonParams = PolygonParams()):
    """A floor fan (camera first) with each ray cut where it crosses a seen wall (the wall
    line within its seen extent): the floor beyond a door is another room's."""
    c, pts = fan[0], fan[1:].copy()
    strong = np.flatnonzero(lines.seen_m >= params.wall_clip_m)
    for k in strong:
        n, d = lines.normals[k], lines.offsets[k]
        u = np.array([n[1], -n[0]])
        m = lines.line_of == k
        proj = np.concatenate([lines.segments[m, 0] @ u, lines.segments[m, 1] @ u])
        lo, hi = proj.min() - params.clip_margin_m, proj.max() + params.clip_margin_m
        den = (pts - c) @ n
        with np.errstate(divide="ignore", invalid="ignore"):
            t = (d - c @ n) / den
        hit = c[None] + t[:, None] * (pts - c)
        s = hit @ u
        cut = (t > 1e-6) & (t < 1.0) & (s >= lo) & (s <= hi)
        pts[cut] = hit[cut]
    return np.vstack([c[None], pts])


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
        for k in np.argsort(lens):
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
    """(V,) whether each edge was seen as a wall over ``seen_share`` of its length."""
    V = len(verts)
    out = np.zeros(V, bool)
    for k in range(V):
        if line[k] < 0:
            continue
        p, q = verts[k], verts[(k + 1) % V]
        Lk = np.linalg.norm(q - p)
        if Lk < 1e-9:
            continue
        u = (q - p) / Lk
        m = lines.line_of == line[k]
        iv = np.sort(np.stack([(lines.segments[m, 0] - p) @ u,
                               (lines.segments[m, 1] - p) @ u], 1), 1)
        iv = np.clip(iv, 0.0, Lk)
        cover = np.zeros(max(2, int(Lk / 0.02)), bool)
        grid = np.linspace(0, Lk, len(cover))
        for a, b in iv:
            cover |= (grid >= a) & (grid <= b)
        out[k] = cover.mean() >= params.seen_share
    return out
