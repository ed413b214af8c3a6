"""The Foxglove view of a floor plan (``findme.v1.Plan``): a ``foxglove.SceneUpdate`` on
``findme/<session>/foxglove/plan`` that Foxglove Studio's 3D panel draws.

One entity, id ``plan`` (each new plan replaces the last), in the frame
``<session>/level/<origin>`` (``schemas.level_frame_id``: the plan frame, y down, floor at
y = camera height), everything on the floor plane y = h:

* walls: blue lines; walls not seen (MISSING): thin red lines (Foxglove draws no dashes);
  openings: orange over their stretch of wall; a wide opening (OPENING): orange;
* each wall's length as a text label ("3.42 m ± 0.03") just outside the wall's midpoint;
* each placed photo: a green arrow from its camera position along its heading, numbered.

Units: metres (or camera heights when the plan is not metric: the labels say "h").
Pure: a message in, (topic, message class, serialised message) out.
"""

from __future__ import annotations

import math

from foxglove_schemas_protobuf.Color_pb2 import Color
from foxglove_schemas_protobuf.LinePrimitive_pb2 import LinePrimitive
from foxglove_schemas_protobuf.SceneUpdate_pb2 import SceneUpdate

import schemas

from .mcap_layout import view_topic

WALL = Color(r=0.10, g=0.31, b=0.61, a=1.0)
MISSING = Color(r=0.75, g=0.22, b=0.17, a=0.8)
OPENING = Color(r=0.96, g=0.65, b=0.14, a=1.0)
CAMERA = Color(r=0.18, g=0.49, b=0.20, a=1.0)
LABEL = Color(r=0.1, g=0.1, b=0.1, a=1.0)


def _point(p, x: float, z: float, y: float) -> None:
    p.x, p.y, p.z = float(x), float(y), float(z)


def plan_view(session: str, plan, log_time: int) -> list[tuple[str, type, bytes]]:
    """The SceneUpdate of ``plan`` (see the module docstring)."""
    up = SceneUpdate()
    e = up.entities.add(id="plan", frame_id=schemas.level_frame_id(session, plan.origin_index),
                        timestamp=schemas.ns_to_timestamp(plan.time_ns or log_time))
    h = plan.camera_height_m or 1.0
    unit = "m" if plan.metric else "h"
    lines = {k: e.lines.add(type=LinePrimitive.LINE_LIST, thickness=t, scale_invariant=True,
                            color=c)
             for k, t, c in (("wall", 4.0, WALL), ("missing", 1.5, MISSING),
                             ("opening", 5.0, OPENING))}
    for w in plan.walls:
        kind = {schemas.WALL_KIND_MISSING: "missing",
                schemas.WALL_KIND_OPENING: "opening"}.get(w.kind, "wall")
        for q in (w.a, w.b):
            _point(lines[kind].points.add(), q.x_m, q.z_m, h)
        dx, dz = w.b.x_m - w.a.x_m, w.b.z_m - w.a.z_m
        L = math.hypot(dx, dz) or 1.0
        for o in w.openings:
            for s in (o.from_m, o.to_m):
                _point(lines["opening"].points.add(), w.a.x_m + s * dx / L, w.a.z_m + s * dz / L, h)
        # outside a counter-clockwise outline: the right of a -> b, seen from above
        mx, mz = (w.a.x_m + w.b.x_m) / 2 + 0.25 * dz / L, (w.a.z_m + w.b.z_m) / 2 - 0.25 * dx / L
        t = e.texts.add(billboard=True, font_size=14.0, scale_invariant=True, color=LABEL,
                        text=f"{w.length_m:.2f} {unit} ± {w.sigma_m:.2f}"
                             + (" (not seen)" if kind == "missing" else ""))
        _point(t.pose.position, mx, mz, h)
        t.pose.orientation.w = 1.0
    for k in [k for k, line in lines.items() if not line.points]:
        e.lines.remove(lines[k])
    for q in plan.poses:
        if q.status != schemas.PLAN_PHOTO_STATUS_PLACED:
            continue
        a = e.arrows.add(shaft_length=0.3, shaft_diameter=0.04, head_length=0.12,
                         head_diameter=0.1, color=CAMERA)
        _point(a.pose.position, q.x_m, q.z_m, h)
        half = (q.yaw_rad - math.pi / 2) / 2   # the arrow's +x turned onto the heading
        a.pose.orientation.y, a.pose.orientation.w = math.sin(half), math.cos(half)
        t = e.texts.add(billboard=True, font_size=12.0, scale_invariant=True, color=CAMERA,
                        text=str(q.index + 1))
        _point(t.pose.position, q.x_m, q.z_m - 0.15, h)
        t.pose.orientation.w = 1.0
    return [(view_topic(session, "plan"), SceneUpdate, up.SerializeToString())]
