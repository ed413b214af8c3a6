"""What each of the room's wall lines (``walls.fit``) is, strongest first: a line B whose
samples were mostly seen through a stronger line A within A's extent (the camera ray
crosses A first, in a gap of A's samples or A much stronger) lies beyond a door or an
opening of A: another room's wall ("beyond"). A line A with a parallel line B behind it
(seen past A's ends, not through it) whose extent covers most of A's is furniture standing
in front of wall B ("furniture"). A weak line is "weak"; the others are the room's walls
("wall"), each carried on to the corners where it meets the next (``complete``).

Frames and units as in ``walls``: (x, z) floor points of the room frame, metres; a line is
n . p = d with unit normal n, direction u = (n_z, -n_x). Pure numpy; no I/O.
"""

from __future__ import annotations

import numpy as np

from findme_core.plan.walls import Evidence, WallLines, WallParams, direction


def crossing(c, q, n, d, extent, margin: float = 0.0):
    """(M, K) whether each ray c -> q (c, q (M, 2)) crosses each line (n (K, 2), d (K,))
    strictly between its ends, within the line's extent (K, 2) widened by ``margin``;
    and (M, K) the ray parameter t in (0, 1) of the crossing (NaN when none)."""
    den = (q - c) @ n.T
    with np.errstate(divide="ignore", invalid="ignore"):
        t = (d[None] - c @ n.T) / den
    hit = c[:, None] + t[..., None] * (q - c)[:, None]
    s = np.einsum("mkj,kj->mk", hit, direction(n))
    ok = (t > 0) & (t < 1) & (s >= extent[None, :, 0] - margin) & (s <= extent[None, :, 1] + margin)
    return ok, np.where(ok, t, np.nan)


def classify(ev: Evidence, lines: WallLines, params: WallParams = WallParams()) -> WallLines:
    """Lines told apart: "beyond" (seen through another line), "furniture" (in front of a
    parallel wall that covers it), else "wall" (see the module docstring)."""
    K = len(lines.normals)
    kind = np.full(K, "wall", object)
    if K == 0:
        return lines
    beyond = np.zeros(K, bool)
    for k in np.argsort(-lines.seen_m, kind="stable"):   # the strongest lines first
        m = lines.sample_line == k
        c, q = ev.cams[ev.photo[m]], ev.points[m]
        q_in = q - 0.1 * (q - c) / np.maximum(np.linalg.norm(q - c, axis=1, keepdims=True), 1e-9)
        through = np.zeros(int(m.sum()), bool)
        for a in np.flatnonzero((lines.seen_m > lines.seen_m[k]) & ~beyond):
            ok, t = crossing(c, q_in, lines.normals[a:a + 1], lines.offsets[a:a + 1],
                             lines.extent[a:a + 1] + [[0.05, -0.05]])
            if not ok.any():
                continue
            if lines.seen_m[a] < params.strength * lines.seen_m[k]:
                # not much stronger: only a ray through a gap in it counts
                s = (c + t[:, :1] * (q_in - c)) @ direction(lines.normals[a])
                seen_a = np.sort(ev.points[lines.sample_line == a] @ direction(lines.normals[a]))
                j = np.clip(np.searchsorted(seen_a, s), 1, len(seen_a) - 1)
                near = np.minimum(np.abs(s - seen_a[j - 1]), np.abs(s - seen_a[j]))
                ok[:, 0] &= near > params.gap_m
            through |= ok[:, 0]
        share = ev.length[m][through].sum() / max(ev.length[m].sum(), 1e-12)
        beyond[k] = share >= params.beyond_share
    ext = complete(lines.normals, lines.offsets, lines.extent, ~beyond, params)
    kind[_furniture(ev, lines, ext, beyond, params)] = "furniture"
    kind[beyond] = "beyond"
    kind[(kind == "wall") & (lines.seen_m < params.min_wall_m)] = "weak"
    wall = kind == "wall"
    return WallLines(lines.normals, lines.offsets, complete(lines.normals, lines.offsets,
                                                            lines.extent, wall, params),
                     lines.seen_m, lines.photos, kind, lines.sample_line, lines.manhattan,
                     lines.snapped)


def complete(normals, offsets, extent, use, params: WallParams = WallParams()) -> np.ndarray:
    """(K, 2) extents of the lines ``use`` (K,) bool, each end carried on to the nearest
    crossing with another such line (at least ``corner_deg`` apart) within ``reach_m``: the
    corner where the wall ends, past a door or an opening next to it."""
    ext = np.array(extent, float).reshape(-1, 2)
    out = ext.copy()
    for k in np.flatnonzero(use):
        u = direction(normals[k])
        best = [np.inf, np.inf]
        for j in np.flatnonzero(use):
            sin = abs(normals[k, 0] * normals[j, 1] - normals[k, 1] * normals[j, 0])
            if j == k or sin < np.sin(np.radians(params.corner_deg)):
                continue
            x = np.linalg.solve(np.array([normals[k], normals[j]]), [offsets[k], offsets[j]])
            s = float(x @ u)
            # the crossing must lie within j's own (reach-widened) extent
            sj = float(x @ direction(normals[j]))
            if not (ext[j, 0] - params.reach_m <= sj <= ext[j, 1] + params.reach_m):
                continue
            for e, sign in ((1, 1.0), (0, -1.0)):   # the nearest crossing at each end
                off = sign * (s - ext[k, e])
                if -params.corner_in_m <= off <= params.reach_m and off < best[e]:
                    best[e], out[k, e] = off, s
    return out


def _furniture(ev: Evidence, lines: WallLines, ext, beyond, params: WallParams) -> np.ndarray:
    """(K,) lines standing in front of a parallel line (not beyond) that covers them."""
    K = len(lines.normals)
    out = np.zeros(K, bool)
    cos_p = np.cos(np.radians(params.parallel_deg))
    for a in np.flatnonzero(~beyond):
        m = lines.sample_line == a
        side = np.sign(np.median(ev.cams[ev.photo[m]] @ lines.normals[a] - lines.offsets[a]))
        la = lines.extent[a, 1] - lines.extent[a, 0]
        for b in np.flatnonzero(~beyond):
            if b == a or abs(lines.normals[a] @ lines.normals[b]) < cos_p:
                continue
            nb, db, eb = lines.normals[b], lines.offsets[b], ext[b]
            if nb @ lines.normals[a] < 0:
                nb, db, eb = -nb, -db, -eb[::-1]
            gap = -side * (db - lines.offsets[a])    # > 0: b lies behind a, seen from a's cameras
            lo, hi = max(eb[0], lines.extent[a, 0]), min(eb[1], lines.extent[a, 1])
            if 0.05 < gap < params.front_max_m and hi - lo >= params.cover_share * la:
                out[a] = True
                break
    return out
