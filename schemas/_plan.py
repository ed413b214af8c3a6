"""Structural checks of a room's floor plan: Plan, its points, walls and photos
(``_validate.VALIDATORS``)."""

from __future__ import annotations

import math

from ._fields import Problems, _enum, _finite, _nonneg, _positive, _session
from .v1 import plan_pb2

_PLACED_FIELDS = ("x_m", "z_m", "yaw_rad")
_PLACED_SIGMAS = ("sigma_x_m", "sigma_z_m", "sigma_yaw_rad", "ambiguity")


def _plan_point(p: Problems, name: str, q: plan_pb2.PlanPoint) -> None:
    _finite(p, f"{name}.x_m", q.x_m)
    _finite(p, f"{name}.z_m", q.z_m)
    sigmas = [f for f in ("sigma_x_m", "sigma_z_m") if q.HasField(f)]
    if len(sigmas) == 1:
        p.append(f"{name} has {sigmas[0]} without the other axis's 1-sigma")
    for f in sigmas:
        _nonneg(p, f"{name}.{f}", getattr(q, f))


def _plan_wall(p: Problems, name: str, w: plan_pb2.PlanWall) -> None:
    _plan_point(p, f"{name}.a", w.a)
    _plan_point(p, f"{name}.b", w.b)
    _positive(p, f"{name}.length_m", w.length_m)
    _nonneg(p, f"{name}.sigma_m", w.sigma_m)
    _enum(p, f"{name}.kind", plan_pb2.WallKind, w.kind, allow_zero=False)
    for i, o in enumerate(w.openings):
        if not (math.isfinite(o.from_m) and math.isfinite(o.to_m)
                and 0 <= o.from_m < o.to_m <= w.length_m + 1e-6):
            p.append(f"{name}.openings[{i}] ({o.from_m!r} to {o.to_m!r} m) must lie within "
                     f"0 <= from_m < to_m <= length_m ({w.length_m!r})")


def _plan_photo(p: Problems, name: str, q: plan_pb2.PlanPhoto) -> None:
    _enum(p, f"{name}.status", plan_pb2.PlanPhotoStatus, q.status, allow_zero=False)
    present = [f for f in _PLACED_FIELDS + _PLACED_SIGMAS if q.HasField(f)]
    if q.status == plan_pb2.PLAN_PHOTO_STATUS_PLACED:
        missing = [f for f in _PLACED_FIELDS if not q.HasField(f)]
        if missing:
            p.append(f"{name} is PLACED but has no {', '.join(missing)}")
        for f in present:
            (_nonneg if f in _PLACED_SIGMAS else _finite)(p, f"{name}.{f}", getattr(q, f))
    elif q.status in plan_pb2.PlanPhotoStatus.values() and q.status:
        if present:
            p.append(f"{name} is not placed, so must carry no numbers, has {', '.join(present)}")
        if not q.reason.strip():
            p.append(f"{name} is not placed and says no reason")


def _plan(m: plan_pb2.Plan) -> Problems:
    p: Problems = []
    _session(p, m.session)
    if m.reason:
        if m.polygon or m.walls:
            p.append("a plan with a reason (no outline yet) must carry no polygon or walls")
    else:
        if len(m.polygon) < 3:
            p.append(f"polygon needs at least 3 vertices, got {len(m.polygon)} (or a reason)")
        if len(m.walls) != len(m.polygon):
            p.append(f"walls must be one per polygon edge: {len(m.polygon)} vertices, "
                     f"{len(m.walls)} walls")
    for i, q in enumerate(m.polygon):
        _plan_point(p, f"polygon[{i}]", q)
    for i, w in enumerate(m.walls):
        _plan_wall(p, f"walls[{i}]", w)
    missing = [i for i, w in enumerate(m.walls) if w.kind == plan_pb2.WALL_KIND_MISSING]
    if m.walls and m.closed == bool(missing):
        p.append(f"closed is {m.closed} but the missing walls are {missing}")
    _nonneg(p, "area_m2", m.area_m2)
    _positive(p, "camera_height_m", m.camera_height_m)
    last = -1
    for i, q in enumerate(m.poses):
        if q.index <= last:
            p.append(f"poses[{i}].index {q.index} out of order (after {last}): photos are "
                     "sorted by index, each at most once")
        last = q.index
        _plan_photo(p, f"poses[{i}]", q)
    for k, v in sorted(m.timing_ms.items()):
        _nonneg(p, f"timing_ms[{k!r}]", v)
    return p
