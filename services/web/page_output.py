"""Bus messages as the JSON a page reads: what the gateway forwards to a page.

    HypothesisSet -> {"type": "hypotheses", ...}     MeasureReply -> {"type": "measure", ...}
    Selection, Scene, Motion, Pose, Trajectory, Error, Plan -> the type of the same name, lower-case
    anything else (a Frame)                           -> None: not for the page

Nothing changes frame or unit on the way: pixels as on the bus ((0, 0) is the centre of the
top-left pixel), metres (``*_m``, up to scale when not metric), radians (``*_rad``), poses
relative to photo 0 and motions of photo B relative to photo A as in ``schemas``, measured
points in camera coordinates, gravity in camera axes. Enums become lower-case names (error
codes upper-case, without their prefix), unset optional fields ``None``, and an error's key
is given relative to the session (``frame/3``). A scene also carries its boundary's walls on
the floor (``walls_m``, the photo's level frame) for the page's floor map, and a hypothesis
set says why its photo does not look like a room view (``not_room_view``,
``findme_core.single.room_view``; "" when it does). Each measured point says what the user said
it is on (``said``: "floor", "wall", "top", or None when nothing was said of it) and what the user
should know of its answer (``note``, e.g. the chosen line runs below a point said floor; None).

Pure: no bus, no server; the message is only read.
"""

from __future__ import annotations

import schemas
from findme_core.errors import FindmeError
from findme_core.single import layout
from findme_io.convert import msg_camera, msg_room_view

from ..runtime import bus

CODE = schemas.ErrorCode


def _opt(m, name):
    return getattr(m, name) if m.HasField(name) else None


def _kind_name(k: int) -> str:
    return schemas.SegKind.Name(k).removeprefix("SEG_KIND_").lower()


def _pose(p) -> dict:
    return {"index": p.index, "x_m": p.x_m, "z_m": p.z_m, "yaw_rad": p.yaw_rad,
            "sigma_x_m": _opt(p, "sigma_x_m"), "sigma_z_m": _opt(p, "sigma_z_m"),
            "sigma_yaw_rad": _opt(p, "sigma_yaw_rad")}


def _walls(scene) -> list:
    """The walls of a Scene's boundary on the floor, [[x0, z0], [x1, z1]] metres in the
    photo's level frame (``findme_core.single.layout``), for the page's floor map; [] when the
    boundary gives none."""
    try:
        poly, kinds = schemas.msg_to_polyline(scene.polyline)
        lay = layout.from_hypothesis(msg_camera(scene.camera), scene.camera_height_m, poly, kinds)
    except FindmeError:
        return []
    return [[[round(float(v), 4) for v in p] for p in w] for w in lay.walls]


def _sources(camera) -> dict:
    """Where a Camera message's lens and gravity came from (the page shows it)."""
    import math
    k = camera.intrinsics
    return {"lens_source": camera.lens_source or None,
            "hfov_deg": math.degrees(2 * math.atan(k.width / (2 * k.fx))) if k.fx > 0 else None,
            "gravity": [camera.gravity.x, camera.gravity.y, camera.gravity.z],
            "gravity_source": camera.gravity_source or None,
            "gravity_sigma_deg": math.degrees(camera.gravity_sigma_rad)}


def _not_room_view(msg) -> str:
    """Why the photo does not look like a room view ("" when it does, or has no hypotheses:
    then its reason says why)."""
    view = msg_room_view(msg)
    return view.reason if view is not None and not view.ok else ""


def to_page(session: str, msg) -> dict | None:
    """A bus message of ``session`` as the JSON the page reads (None: not for the page)."""
    name = type(msg).__name__
    if name == "HypothesisSet":
        return {"type": "hypotheses", "index": msg.index, "width": msg.width,
                "height": msg.height, "reason": msg.reason, "method": msg.method,
                "not_room_view": _not_room_view(msg), "timing_ms": dict(msg.timing_ms),
                "hypotheses": [{"rank": h.rank, "score": h.score, "support": h.support,
                                "points": [[p.u, p.v] for p in h.polyline.points],
                                "kinds": [_kind_name(k) for k in h.polyline.kinds]}
                               for h in msg.hypotheses],
                "camera": _sources(msg.camera) if msg.HasField("camera") else None}
    if name == "Selection":
        return {"type": "selection", "index": msg.index, "rank": msg.rank,
                "by": "user" if msg.by == schemas.SELECTED_BY_USER else "auto",
                "camera_height_m": _opt(msg, "camera_height_m")}
    if name == "Scene":
        return {"type": "scene", "index": msg.index, "rank": msg.rank, "metric": msg.metric,
                "camera_height_m": msg.camera_height_m, **_sources(msg.camera),
                "walls_m": _walls(msg)}
    if name == "Motion":
        d = {"type": "motion", "a": msg.index_a, "b": msg.index_b, "error": msg.error,
             "inliers": msg.inliers, "matches": msg.matches, "method": msg.method}
        for k in ("x_m", "z_m", "yaw_rad", "sigma_x_m", "sigma_z_m", "sigma_yaw_rad", "score",
                  "appearance"):
            d[k] = _opt(msg, k)
        d["scale_points"] = msg.scale_points
        # the evidence: how many walls and corners of the two photos' layouts agree, and
        # the other motions the evidence allows nearly as well (a symmetric room)
        d["layout"] = ({"walls": len(msg.layout.walls), "corners": len(msg.layout.corners),
                        "samples": msg.layout.samples}
                       if msg.HasField("layout") else None)
        d["alternatives"] = [{"x_m": a.x_m, "z_m": a.z_m, "yaw_rad": a.yaw_rad,
                              "score": _opt(a, "score")} for a in msg.alternatives]
        return d
    if name == "Pose":
        return {"type": "pose", **_pose(msg)}
    if name == "Trajectory":
        return {"type": "trajectory", "poses": [_pose(p) for p in msg.poses]}
    if name == "Error":
        prefix = f"{bus.ROOT}/{session}/"
        return {"type": "error", "code": CODE.Name(msg.code).removeprefix("ERROR_CODE_"),
                "message": msg.message, "key": msg.key.removeprefix(prefix),
                "service": msg.service}
    if name == "MeasureReply":
        return {"type": "measure", "index": msg.index, "rank": msg.rank, "metric": msg.metric,
                "error": msg.error,
                "points": [{"pixel": [p.pixel.u, p.pixel.v],
                            "surface": schemas.Surface.Name(p.surface).removeprefix("SURFACE_").lower(),
                            "xyz": [p.xyz.x, p.xyz.y, p.xyz.z] if p.HasField("xyz") else None,
                            "sigma_m": _opt(p, "sigma_m"), "error": p.error,
                            "note": p.note or None,
                            "said": schemas.surface_name(p.said)} for p in msg.points],
                "distances": [{"a": d.a, "b": d.b, "distance_m": _opt(d, "distance_m"),
                               "sigma_m": _opt(d, "sigma_m"), "error": d.error}
                              for d in msg.distances]}
    if name == "Plan":
        return plan_to_page(msg)
    return None


def plan_to_page(m) -> dict:
    """A Plan as the page draws it: points as [x_m, z_m] (plan frame: the level frame of
    photo ``origin_index``), wall and photo kinds as lower-case names."""
    def xz(q):
        return [q.x_m, q.z_m]

    def kind(enum, v, prefix):
        return enum.Name(v).removeprefix(prefix).lower()
    return {"type": "plan", "up_to_index": m.up_to_index, "photos": m.photos,
            "origin_index": m.origin_index, "metric": m.metric,
            "camera_height_m": m.camera_height_m, "reason": m.reason, "area_m2": m.area_m2,
            "closed": m.closed, "manhattan": m.manhattan,
            "polygon": [xz(q) for q in m.polygon],
            "corner_sigma_m": [[q.sigma_x_m, q.sigma_z_m] if q.HasField("sigma_x_m") else None
                               for q in m.polygon],
            "walls": [{"a": xz(w.a), "b": xz(w.b), "length_m": w.length_m,
                       "sigma_m": None if w.kind == schemas.WALL_KIND_MISSING else w.sigma_m,
                       "kind": kind(schemas.WallKind, w.kind, "WALL_KIND_"),
                       "openings": [[o.from_m, o.to_m] for o in w.openings]} for w in m.walls],
            "poses": [{"index": q.index, "spot": q.spot, "reason": q.reason,
                       "status": kind(schemas.PlanPhotoStatus, q.status, "PLAN_PHOTO_STATUS_"),
                       **{k: _opt(q, k) for k in ("x_m", "z_m", "yaw_rad", "sigma_x_m",
                                                  "sigma_z_m", "sigma_yaw_rad", "ambiguity")}}
                      for q in m.poses]}
