"""The outline's 1-sigmas without the joint refinement: each wall line's offset, each wall's
length and each corner's position, from the spread of the wall samples about their lines.

A wall line's offset is known to the spread of its samples about it over the square root of
their number. A corner is the intersection of its two walls' lines: it moves with both
offsets, n_a . dV = dd_a and n_b . dV = dd_b, so dV = A^-1 dd with A = [n_a; n_b] (rows),
and a wall's length with the corners at its two ends. Every distance also scales with the
camera height (relative 1-sigma ``height_rel``): a length by its length, a corner by its
distance from the origin photo. Lines meeting at under ``MIN_SIN`` (11.5 deg) are taken as
meeting at that angle (their intersection slides without bound as they turn parallel); a
corner off any wall line (-1: only the floor raster bounds it) moves by ``RASTER_M``.

Frames and units: the room frame (x right, z forward of the first photo; metres); lines as
``polygon.Lines`` (unit normals (K, 2), offsets); ``polygon.Outline.line`` (V,) the line of
wall k (vertex k to k + 1), -1 for none. Pure numpy; no I/O.
"""

from __future__ import annotations

import math

import numpy as np

from findme_core.plan import polygon, walls

#: the smallest sine of the angle two wall lines are taken to meet at
MIN_SIN = 0.2
#: 1-sigma, metres, of a corner's position along an axis no wall line fixes
RASTER_M = 0.1


def offset_sigmas(ev: walls.Evidence, wl: walls.WallLines, floor_m: float) -> np.ndarray:
    """(K,) 1-sigma of each wall line's offset, metres: the RMS of its samples about it over
    the square root of their number, at least ``floor_m`` (``RASTER_M`` with fewer than 2
    samples)."""
    out = np.full(len(wl.walls), RASTER_M)
    for i, k in enumerate(wl.walls):
        m = wl.sample_line == k
        e = ev.points[m] @ wl.normals[k] - wl.offsets[k]
        if len(e) >= 2:
            out[i] = max(float(np.sqrt(np.mean(e ** 2)) / np.sqrt(len(e))), floor_m)
    return out


def length_sigmas(out: polygon.Outline, lines: polygon.Lines, sig_d,
                  height_rel: float) -> np.ndarray:
    """(V,) wall length 1-sigma, metres: each end moves with its neighbour's offset,
    sigma_L^2 = sum over both neighbours of (sigma_d / sin(angle))^2, plus the camera
    height's relative error times L."""
    V = out.vertices
    res = []
    for k in range(len(V)):
        length = float(np.linalg.norm(V[(k + 1) % len(V)] - V[k]))
        s2 = (height_rel * length) ** 2
        for j in (k - 1, (k + 1) % len(V)):
            lk, lj = out.line[k], out.line[j]
            if lk >= 0 and lj >= 0:
                na, nb = lines.normals[lk], lines.normals[lj]
                sin = abs(float(na[0] * nb[1] - na[1] * nb[0]))
                s2 += (sig_d[lj] / max(sin, MIN_SIN)) ** 2
            else:
                s2 += RASTER_M ** 2
        res.append(math.sqrt(s2))
    return np.array(res)


def corner_sigmas(out: polygon.Outline, lines: polygon.Lines, sig_d,
                  height_rel: float) -> np.ndarray:
    """(V, 2) 1-sigma of each vertex's x and z, metres: vertex k, where wall k - 1 meets
    wall k, moved by both lines' offsets (dV = A^-1 dd, A their normals as rows, |det A| at
    least ``MIN_SIN``) and by the camera height along its distance from the origin."""
    V = out.vertices
    res = np.empty((len(V), 2))
    for k in range(len(V)):
        la, lb = out.line[k - 1], out.line[k]
        if la < 0 or lb < 0:
            var = np.full(2, RASTER_M ** 2)
        else:
            A = np.array([lines.normals[la], lines.normals[lb]], float)
            det = float(A[0, 0] * A[1, 1] - A[0, 1] * A[1, 0])
            inv = np.array([[A[1, 1], -A[0, 1]], [-A[1, 0], A[0, 0]]]) / math.copysign(
                max(abs(det), MIN_SIN), det)
            var = (inv ** 2) @ (np.array([sig_d[la], sig_d[lb]], float) ** 2)
        res[k] = np.sqrt(var + (height_rel * V[k]) ** 2)
    return res
