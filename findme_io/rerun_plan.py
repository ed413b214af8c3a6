"""The floor plan in Rerun: ``log_plan(rec, path, plan)`` (frames: see ``rerun_views``)."""

from __future__ import annotations

import math

import numpy as np

import schemas

from .rerun_views import _rr, photo_path

PLAN_WALL_RGBA = (26, 79, 156, 255)
PLAN_MISSING_RGBA = (192, 57, 43, 200)
PLAN_OPENING_RGBA = (245, 166, 35, 255)
PLAN_CAMERA_RGBA = (46, 125, 50, 255)


def log_plan(rec, path: str, plan) -> None:
    """A floor plan (``path`` = plan): top-down 2D at ``path`` (x right, forward z UP: 2D
    (x, -z), metres) and in 3D on the floor (y = h) of the plan frame, the level frame of
    photo ``origin_index`` (``world/photo/<origin>/plan``). Walls with their lengths as
    labels (seen: blue; not seen: thin red, "(not seen)"; openings orange), each placed
    photo's position and heading, numbered; a plan without an outline clears the walls,
    still draws the photos it placed (an outline refused: ``OutlineRefused``) and says why
    in the session's log (``log``)."""
    rr = _rr()
    if plan.reason:
        rec.log("log", rr.TextLog(f"plan of photos up to {plan.up_to_index + 1}: no outline: "
                                  f"{plan.reason}", level="WARN"))
    h = plan.camera_height_m or 1.0
    unit = "m" if plan.metric else "h"
    world = f"{photo_path(plan.origin_index)}/plan"
    groups = {"walls": ([], [], PLAN_WALL_RGBA, 0.04), "missing": ([], [], PLAN_MISSING_RGBA, 0.02),
              "openings": ([], [], PLAN_OPENING_RGBA, 0.06)}
    for w in plan.walls:
        g = {schemas.WALL_KIND_MISSING: "missing", schemas.WALL_KIND_OPENING: "openings"}.get(
            w.kind, "walls")
        a, b = np.array([w.a.x_m, w.a.z_m]), np.array([w.b.x_m, w.b.z_m])
        groups[g][0].append(np.array([a, b]))
        groups[g][1].append(f"{w.length_m:.2f} {unit} (not seen: inferred, not measured)"
                            if g == "missing" else f"{w.length_m:.2f} {unit} ± {w.sigma_m:.2f}")
        u = (b - a) / max(w.length_m, 1e-9)
        for o in w.openings:
            groups["openings"][0].append(np.array([a + o.from_m * u, a + o.to_m * u]))
            groups["openings"][1].append(f"opening {o.to_m - o.from_m:.2f} {unit}")
    for name, (segs, labels, rgba, radius) in groups.items():
        if not segs:
            rec.log(f"{path}/{name}", rr.Clear(recursive=False))
            rec.log(f"{world}/{name}", rr.Clear(recursive=False))
            continue
        flat = [np.column_stack([s[:, 0], -s[:, 1]]) for s in segs]
        rec.log(f"{path}/{name}", rr.LineStrips2D(flat, colors=[rgba], radii=[radius],
                                                  labels=labels, show_labels=True))
        up = [np.column_stack([s[:, 0], np.full(2, h), s[:, 1]]) for s in segs]
        rec.log(f"{world}/{name}", rr.LineStrips3D(up, colors=[rgba], radii=[radius / 2],
                                                   labels=labels, show_labels=True))
    cams = [q for q in plan.poses if q.status == schemas.PLAN_PHOTO_STATUS_PLACED]
    if not cams:
        rec.log(f"{path}/cameras", rr.Clear(recursive=False))
        rec.log(f"{world}/cameras", rr.Clear(recursive=False))
        return
    xz = np.array([(q.x_m, q.z_m) for q in cams])
    fwd = 0.35 * np.array([(math.sin(q.yaw_rad), math.cos(q.yaw_rad)) for q in cams])
    labels = [str(q.index + 1) for q in cams]
    rec.log(f"{path}/cameras", rr.Arrows2D(origins=xz * [1, -1], vectors=fwd * [1, -1],
                                           colors=[PLAN_CAMERA_RGBA], radii=[0.02],
                                           labels=labels, show_labels=True))
    rec.log(f"{world}/cameras", rr.Arrows3D(
        origins=np.column_stack([xz[:, 0], np.full(len(xz), h), xz[:, 1]]),
        vectors=np.column_stack([fwd[:, 0], np.zeros(len(xz)), fwd[:, 1]]),
        colors=[PLAN_CAMERA_RGBA], labels=labels, show_labels=True))
