"""Find me on a plan: where a new photo was taken in a mapped room, by registering its
layout to the plan's walls.

Frames: the plan's room frame (x, z metres; ``floorplan``); the photo's level frame; a pose
(x, z, yaw) maps a floor point p of the photo to R(yaw) p + (x, z) (``register.rot2``).

Candidates: a photo wall put on a plan wall with the camera on the room's side fixes the
yaw; two such non-parallel pairs fix the position. Each candidate with the camera inside the
outline is scored by the photo's wall-base samples: on a plan wall (within ``gate_m``, MSAC
weight) they agree; beyond the outline by more than the gate (floor where the room has
none) they count against it. A symmetric room gives several poses with nearly equal scores:
all are returned, best first, and the ambiguity says how close the runner-up is.

Pure numpy + OpenCV; no I/O.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from findme_core.errors import GeometryError
from findme_core.geometry import ties
from findme_core.geometry.planar import wrap
from findme_core.motion import register
from findme_core.plan.floorplan import Plan
from findme_core.single.layout import Layout, merged
from findme_core.single.search import SegKind


@dataclass(frozen=True)
class Located:
    """A pose of the photo on the plan: x, z metres, yaw radians, its score (agreeing
    samples minus violating ones), agreeing samples and rms distance to the walls (m)."""

    x: float
    z: float
    yaw: float
    score: float
    agreeing: int
    rms_m: float


def locate(plan: Plan, L: Layout, gate_m: float = 0.12, max_walls: int = 8,
           keep: int = 4) -> list[Located]:
    """Poses of a photo with layout ``L`` on ``plan``, best first (distinct: 10 deg or
    0.3 m apart; at most ``keep``).

    Raises:
        GeometryError: the photo shows no wall, or no pose puts it inside the room.
    """
    if len(L.walls) == 0:
        raise GeometryError("the photo shows no wall base: nothing to register on the plan")
    V = plan.polygon
    a, b = V, np.roll(V, -1, axis=0)
    seen = np.array([w.seen for w in plan.walls], bool)
    d = b - a
    lens = np.linalg.norm(d, axis=1)
    n_in = np.column_stack([-d[:, 1], d[:, 0]]) / np.maximum(lens, 1e-12)[:, None]  # CCW: left
    off = np.einsum("ij,ij->i", n_in, a)
    pn = L.normals                                    # toward the photo's camera
    pd = np.einsum("ij,ij->i", pn, L.walls[:, 0])
    plen = np.linalg.norm(L.walls[:, 1] - L.walls[:, 0], axis=1)
    order = ties.order(plen)[:max_walls]   # walls of one length: in index order
    cands = []
    for i in order:
        for k in np.flatnonzero(seen):
            # R(yaw) pn_i = n_in_k: the camera side of the photo wall is the room side
            yaw = np.arctan2(pn[i, 1], pn[i, 0]) - np.arctan2(n_in[k, 1], n_in[k, 0])
            R = register.rot2(np.array([yaw]), pn[None])[0]   # rotated normals (K, 2)
            for j in order:
                for m in np.flatnonzero(seen):
                    if j == i or m == k or abs(n_in[k, 0] * n_in[m, 1] - n_in[k, 1] * n_in[m, 0]) < 0.5:
                        continue
                    if R[j] @ n_in[m] < 0.9:
                        continue
                    # n_in . (R p + t) = off for both walls; R p . n_in = pd (rotation-invariant)
                    A = np.array([n_in[k], n_in[m]])
                    rhs = np.array([off[k] - pd[i], off[m] - pd[j]])
                    t = np.linalg.solve(A, rhs)
                    cands.append((t[0], t[1], float(wrap(yaw))))
    if not cands:
        raise GeometryError("no two walls of the photo match two walls of the plan")
    c = np.unique(np.round(np.array(cands), 3), axis=0)
    poly = V.astype(np.float32).reshape(-1, 1, 2)
    inside = np.array([cv2.pointPolygonTest(poly, (float(x), float(z)), False) > 0
                       for x, z, _ in c])
    c = c[inside]
    if not len(c):
        raise GeometryError("no pose that matches the photo's walls puts it inside the room")
    pts = L.points[(L.kind == SegKind.WALL) & np.isfinite(L.range)]
    scored = [_score(p, pts, a, b, seen, poly, gate_m) for p in c]
    # best first; poses that score alike (a symmetric room turned half round) in the order
    # of their candidates, so that every machine names the same one first
    o = ties.order(np.array([s[0] for s in scored]))
    out = []
    for k in o:
        x, z, yaw = c[k]
        if all(abs(wrap(yaw - q.yaw)) > np.radians(10) or np.hypot(x - q.x, z - q.z) > 0.3
               for q in out):
            out.append(Located(float(x), float(z), float(yaw), *scored[k]))
        if len(out) >= keep:
            break
    return out


def _score(pose, pts, a, b, seen, poly, gate):
    q = register.rot2(np.array([pose[2]]), pts)[0] + pose[:2]
    d = b - a
    t = np.clip(np.einsum("sij,ij->si", q[:, None] - a[None], d) / np.maximum(
        np.einsum("ij,ij->i", d, d), 1e-12), 0, 1)
    dist = np.linalg.norm(q[:, None] - (a[None] + t[..., None] * d[None]), axis=2)
    dist = np.where(seen[None], dist, np.inf).min(1)
    agree = dist < gate
    out = np.array([cv2.pointPolygonTest(poly, (float(x), float(z)), True) for x, z in q])
    viol = (~agree) & (out < -gate)
    sc = float(np.sum(1.0 - (dist[agree] / gate) ** 2) - viol.sum())
    rms = float(np.sqrt(np.mean(dist[agree] ** 2))) if agree.any() else float("nan")
    return sc, int(agree.sum()), rms



def locate_turn(plan: Plan, layouts, block, rel, **kw) -> tuple[np.ndarray, list[Located]]:
    """Poses of K photos taken at one place (a turn) on ``plan``, best first: the block of
    photos its rotation-only yaws join (``block`` (K,), ``rel`` (K,) each photo's yaw in its
    block, radians, ``fuse.blocks``) with the most layouts has its layouts merged into one
    (``layout.merged``: more walls than any one photo shows), located as ``locate`` locates
    one photo (keyword arguments as there).

    Returns:
        (poses (C, K, 3): every photo of that block, NaN rows for the others; the C
        ``Located`` of its first photo with a layout).

    Raises:
        GeometryError: as ``locate``; HypothesisError: no layout.
    """
    has = np.array([L is not None for L in layouts])
    main = int(np.argmax(np.bincount(block, weights=has)))
    idx = [k for k in range(len(layouts)) if block[k] == main and has[k]]
    found = locate(plan, merged([layouts[k] for k in idx], [rel[k] - rel[idx[0]] for k in idx]),
                   **kw)
    poses = np.full((len(found), len(layouts), 3), np.nan)
    for c, p in enumerate(found):
        for k in np.flatnonzero(block == main):
            poses[c, k] = (p.x, p.z, wrap(p.yaw + rel[k] - rel[idx[0]]))
    return poses, found


#: A found pose is stated only when the runner-up scores less than this share of it.
FOUND_RATIO = 0.8

#: 1-sigma of a stated pose, (x and z each: metres, yaw: degrees), fitted on the poses stated
#: on the dev rooms (``tools/locate_report.py``: 35 photos of 8 turns in 4 rooms; each spot
#: found on the plan of the others) by the rule the product's sigma constants are fitted by
#: (``sigma_coverage.fit_factor``: coverage nearest the goal, then a Gaussian's). Left
#: out room by room (each room with the value fitted on the others, 0.044-0.049 m and
#: 0.49-0.54 deg), 0.77 / 0.97 / 0.97 of x and z lie within 1 / 2 / 3 sigma and 0.60 / 1.00 /
#: 1.00 of the yaws (2026-12-02, by both the goal-first rule and the Gaussian-nearest one
#: before it; the RMS errors used before, 0.043 m and 0.47 deg, left 0.54 / 0.97 / 0.97 and
#: 0.57 / 1.00 / 1.00). Eight turns are few: a constant, not a model.
FOUND_SIGMA = (0.044, 0.53)


def verdict(scores, with_photos: bool, turn: bool,
            ratio: float = FOUND_RATIO) -> tuple[bool, str | None]:
    """Whether "find me" can state its best pose, or only give its candidates, and why not.

    ``scores``: (C,) the candidates' scores, best first; ``with_photos``: the plan's photos
    took part (feature matches and motions), not the plan's walls alone; ``turn``: several
    photos taken standing at one place, found together.

    Measured on the dev rooms, each spot found on the plan of the others
    (``tools/locate_report.py``, 54 photos), the best candidate was the right pose (0.25 m,
    5 deg) for 7 photos from the plan's walls alone, 18 turning; with the plan's photos 24
    alone, 39 turning. So a pose is stated only from a turn with the plan's photos, whose best
    scores above zero and whose runner-up scores under ``ratio`` of it: 35 stated there, all
    right (the 15 others given as candidates, the right one among them each time). Anything
    else gives the candidates: a room's walls fit several poses alike (a rectangle turned half
    round, a corner like every corner), and one photo's matches leave too few walls in view.

    Returns:
        (True, None) to state the best pose; (False, the reason) to give the candidates.
    """
    sc = np.asarray(scores, float)
    if len(sc) == 0:
        raise GeometryError("no candidate pose to judge")
    if not with_photos:
        return False, ("the plan's walls alone fit several places alike; give the plan's "
                       "photos (--photos) and take photos all round where you stand")
    if not turn:
        return False, ("one photo shows too little of the room to tell these places apart; "
                       "take photos all round where you stand")
    if not sc[0] > 0:
        return False, "no place fits the plan better than it contradicts it"
    if len(sc) > 1 and not sc[1] < ratio * sc[0]:
        return False, (f"the runner-up fits {sc[1] / sc[0]:.0%} as well as the best; take "
                       "more photos all round where you stand")
    return True, None
