"""Doors and openings in a wall of the outline: stretches where a photo saw floor beyond the
wall, and no more photos saw the wall's base standing there.

A photo's floor fan (``fans``: the floor its layout saw, camera first) that reaches past a
wall says the floor continues there: a door or an opening. One photo's layout can be wrong:
its top hypothesis can be a far line (a poster's lower edge on the wall ahead), and its fan
then runs metres past a wall its neighbours saw standing. Another can see a threshold (a
change of flooring in the opening, which the dataset's rooms draw as the wall) as a wall's
base. So each photo has one vote at each point of the wall: the floor goes on (its fan
reaches past) or the wall stands (a wall-base sample of it on the wall's line there); an
opening needs the first at least as many votes as the second.

Frames and units: the room frame (x, z metres); a wall runs a -> b, the polygon is
counter-clockwise, so its outward normal is (u_z, -u_x) for u = (b - a) / |b - a|; stretches
are (from_m, to_m) measured from a. Pure numpy + OpenCV point-in-polygon; no I/O.
"""

from __future__ import annotations

import cv2
import numpy as np

from findme_core.motion import register
from findme_core.single.layout import Layout
from findme_core.single.search import SegKind


def fans(L: Layout, pose, max_range_m: float = 8.0) -> list:
    """Polygons (F, 2) (camera first, then boundary samples in azimuth order) of the floor a
    layout saw, in the room frame at ``pose`` (x, z, yaw); split where no floor was seen
    (NONE samples); ranges cut at ``max_range_m``."""
    ok = np.isfinite(L.range) & (L.kind != SegKind.NONE)
    r = np.minimum(np.where(ok, L.range, 0.0), max_range_m)
    pts = r[:, None] * np.column_stack([np.sin(L.azimuth), np.cos(L.azimuth)])
    out, cur = [], []
    for k in range(len(pts)):
        if ok[k]:
            cur.append(pts[k])
        elif cur:
            out.append(cur)
            cur = []
    if cur:
        out.append(cur)
    polys = []
    for c in out:
        if len(c) >= 2:
            P = np.vstack([np.zeros((1, 2)), np.array(c)])
            polys.append(register.rot2(np.array([pose[2]]), P)[0] + pose[:2])
    return polys


def session_fans(layouts, poses, max_range_m: float = 8.0) -> tuple[list, np.ndarray]:
    """(fans, (F,) photo of each) of N photos' layouts (None: none) at poses (N, 3) (NaN
    rows: not placed)."""
    polys, photo = [], []
    for i, (L, p) in enumerate(zip(layouts, np.asarray(poses, float).reshape(-1, 3))):
        if L is not None and np.isfinite(p[0]):
            f = fans(L, p, max_range_m)
            polys += f
            photo += [i] * len(f)
    return polys, np.asarray(photo, int)


def base_seen(a, b, s, base, base_length=None, near_m: float = 0.25) -> np.ndarray:
    """(S,) whether a wall-base sample stands at each station ``s`` (S,) (metres from a) of
    the wall a -> b: within ``near_m`` of its line, and along it within half the floor length
    the sample stands for (``base_length`` (B,), default 0) plus half the stations' step.

    Args:
        a, b: (2,) the wall's ends; base: (B, 2) wall-base samples of every photo (room frame).
    """
    a, b = np.asarray(a, float), np.asarray(b, float)
    s = np.asarray(s, float)
    base = np.asarray(base, float).reshape(-1, 2)
    if not len(s) or not len(base):
        return np.zeros(len(s), bool)
    u = (b - a) / max(float(np.linalg.norm(b - a)), 1e-12)
    n = np.array([u[1], -u[0]])
    along, off = (base - a) @ u, (base - a) @ n
    half = 0.5 * (np.zeros(len(base)) if base_length is None
                  else np.asarray(base_length, float).reshape(-1))
    half = half + 0.5 * (float(s[1] - s[0]) if len(s) > 1 else 0.0)
    on = np.abs(off) <= near_m
    return (np.abs(s[:, None] - along[None, on]) <= half[None, on]).any(axis=1)


def stretches(a, b, floor_fans, fan_photo=None, base=None, base_length=None, base_photo=None,
              min_m: float = 0.5, beyond_m: float = 0.25, step_m: float = 0.05) -> tuple:
    """Doors and openings of the wall a -> b: ((from_m, to_m), ...) stretches at least
    ``min_m`` long where the photos whose floor fans (``fans``; ``fan_photo`` (F,) the photo
    of each, default one photo per fan) cover the floor ``beyond_m`` outside the wall are at
    least as many as the photos with a wall-base sample standing there (``base`` (B, 2),
    ``base_length`` (B,), ``base_photo`` (B,); ``base_seen``): each photo has one vote on
    whether the floor goes on, and a tie leaves the opening. A wall shorter than ``min_m``
    has none."""
    a, b = np.asarray(a, float), np.asarray(b, float)
    L = float(np.linalg.norm(b - a))
    if L < min_m:
        return ()
    u = (b - a) / L
    n_out = np.array([u[1], -u[0]])   # outward for a counter-clockwise polygon
    s = np.arange(step_m / 2, L, step_m)
    pts = a[None] + s[:, None] * u[None] + beyond_m * n_out[None]
    fan_photo = np.arange(len(floor_fans)) if fan_photo is None else np.asarray(fan_photo)
    beyond = {}
    for f, i in zip(floor_fans, fan_photo):
        c = np.asarray(f, np.float32).reshape(-1, 1, 2)
        beyond[int(i)] = beyond.get(int(i), np.zeros(len(s), bool)) | np.array(
            [cv2.pointPolygonTest(c, (float(x), float(z)), False) > 0 for x, z in pts])
    votes = sum(beyond.values(), np.zeros(len(s), int))
    if base is not None and len(base):
        base = np.asarray(base, float).reshape(-1, 2)
        ln = np.zeros(len(base)) if base_length is None else np.asarray(base_length, float)
        bp = np.zeros(len(base), int) if base_photo is None else np.asarray(base_photo, int)
        against = sum((base_seen(a, b, s, base[bp == i], ln[bp == i], beyond_m).astype(int)
                       for i in np.unique(bp)), np.zeros(len(s), int))
        hit = (votes > 0) & (votes >= against)
    else:
        hit = votes > 0
    out, start = [], None
    for i, h in enumerate(np.append(hit, False)):
        if h and start is None:
            start = i
        elif not h and start is not None:
            if (i - start) * step_m >= min_m:
                out.append((round(float(s[start] - step_m / 2), 3),
                            round(float(min(L, s[i - 1] + step_m / 2)), 3)))
            start = None
    return tuple(out)
