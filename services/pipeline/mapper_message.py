"""The mapper's Plan message from a core plan (``floorplan.Plan``) and its placement: the
outline and its corners' 1-sigmas, the walls (seen, openings, missing: a wall nobody saw and
its corners have no 1-sigma), each photo's pose and 1-sigma or the reason it is not placed.

Frames and units: the plan frame (the level frame of its first photo), metres, radians.
"""

from __future__ import annotations

import numpy as np

import schemas
from findme_core.plan import fuse, pose as plan_pose

#: A seen edge with floor seen beyond at least this share of it is an opening, not a wall.
OPENING_SHARE = 0.9


def fill(msg, plan, pl, timing, photos, order, status, outline: bool = True) -> None:
    """The core plan into the message; each photo's status into ``status`` (n -> PlanPhoto).
    ``outline`` False (a refused outline, ``OutlineRefused``: ``msg.reason`` says why): the
    photos' poses only, no polygon or walls, and no 1-sigma taken from those walls."""
    for stage, ms in timing.items():
        msg.timing_ms[stage] = max(float(ms), 0.0)
    if outline:
        _outline(msg, plan)
    for a, n in enumerate(order):
        status[n] = _photo(plan, pl, photos, a, n, outline)


def _outline(msg, plan) -> None:
    for v, s in zip(plan.polygon, plan.corner_sigma):
        q = msg.polygon.add(x_m=float(v[0]), z_m=float(v[1]))
        if np.all(np.isfinite(s)):   # a corner of a wall nobody saw: inferred, no 1-sigma
            q.sigma_x_m, q.sigma_z_m = map(float, s)
    for w in plan.walls:
        gaps = sum(b - a for a, b in w.apertures)
        kind = (schemas.WALL_KIND_MISSING if not w.seen else schemas.WALL_KIND_OPENING
                if gaps >= OPENING_SHARE * w.length_m else schemas.WALL_KIND_WALL)
        # a wall nobody saw is inferred, not measured: no 1-sigma (0, unset; kind MISSING)
        sigma = float(w.sigma_m) if np.isfinite(w.sigma_m) else 0.0
        pw = msg.walls.add(length_m=float(w.length_m), sigma_m=sigma, kind=kind)
        pw.a.x_m, pw.a.z_m, pw.b.x_m, pw.b.z_m = map(float, (*w.a, *w.b))
        for a, b in w.apertures:
            pw.openings.add(from_m=float(a), to_m=float(min(b, w.length_m)))
    msg.area_m2, msg.closed, msg.manhattan = float(plan.area_m2), plan.closed, plan.manhattan


def _photo(plan, pl, photos, a: int, n: int, walls_stand: bool = True):
    """Photo ``a`` of the plan (its index ``n`` in the session) as a PlanPhoto; its 1-sigma
    the joint refinement's, else (``walls_stand``) from its wall samples on the plan's walls."""
    p = plan.poses[a]
    q = schemas.PlanPhoto(index=n, spot=int(pl.spot[a]))
    if np.all(np.isfinite(p)):
        q.status = schemas.PLAN_PHOTO_STATUS_PLACED
        q.x_m, q.z_m, q.yaw_rad = float(p[0]), float(p[1]), float(fuse.wrap(p[2]))
        sig = plan.pose_sigma[a] if plan.pose_sigma is not None else np.full(3, np.nan)
        if walls_stand and not np.all(np.isfinite(sig)):   # not refined jointly: its walls
            C = plan_pose.covariance(plan, photos[a].layout, p)
            sig = np.sqrt(np.maximum(np.diag(C), 0.0)) if C is not None else sig
        if np.all(np.isfinite(sig)):
            q.sigma_x_m, q.sigma_z_m, q.sigma_yaw_rad = map(float, sig)
        if a < len(plan.ambiguity) and np.isfinite(plan.ambiguity[a]):
            q.ambiguity = max(float(plan.ambiguity[a]), 0.0)
    else:
        q.status = schemas.PLAN_PHOTO_STATUS_NOT_PLACED
        q.reason = (plan.notes[a] if a < len(plan.notes) and plan.notes[a]
                    else "not placed")
    return q
