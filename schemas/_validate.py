"""Per-type structural checks of bus messages (no geometry, no findme_core).

A check returns the list of problems of one message; each problem names the field and the
offending value. What is checked is what a consumer could not do without: the session id
is usable in a key, required parts are present, numbers are finite and in range, enum
values are known, repeated fields agree in length, and a failure carries no numbers.
Geometry (is the camera sane, does the boundary span the image) is left to the services.
"""

from __future__ import annotations

import math
import re
from collections.abc import Callable
from typing import Any

from google.protobuf.message import Message

from .v1 import common_pb2, frame_pb2, hypotheses_pb2, measure_pb2, motion_pb2, scene_pb2
from .v1 import plan_pb2, selection_pb2, status_pb2

#: A session id: safe as one Zenoh key chunk and as a file name.
SESSION_PATTERN = r"[A-Za-z0-9_-][A-Za-z0-9_.-]{0,127}"
_SESSION_RE = re.compile(SESSION_PATTERN + r"\Z")

#: Image formats of foxglove.CompressedImage (Foxglove's own names).
IMAGE_FORMATS = ("jpeg", "png", "webp", "avif")

Problems = list[str]

#: Lines a HypothesisSet may carry (a 12 MP photo has a few hundred merged lines).
MAX_LINES = 4096
#: Points a boundary polyline may carry (the product's have tens; locating N pixels on one
#: costs N x points of memory: 1024 x 4096 pairs, ~100 MB at most).
MAX_POLYLINE_POINTS = 4096
#: Alternatives a Motion may carry, and wall / corner pairs of its layout evidence.
MAX_ALTERNATIVES = 8
MAX_LAYOUT_PAIRS = 64
#: Pixels one MeasureRequest may ask for (taps, not an image: locating 100,000 pixels costs
#: the measurement service ~5 s of CPU and ~150 MB, 2026-11-30).
MAX_MEASURE_PIXELS = 1024
#: Gravity alternatives a Camera may carry.
MAX_GRAVITY_ALTERNATIVES = 8
#: Frame.heading_ref: the page's sensors (""), true or magnetic north, a compass's unsaid
HEADING_REFS = frozenset({"", "T", "M", "?"})


def is_valid_session(session: object) -> bool:
    """True when ``session`` is a usable session id (see SESSION_PATTERN)."""
    return isinstance(session, str) and _SESSION_RE.match(session) is not None


def _short(value: Any, limit: int = 60) -> str:
    r = repr(value)
    return r if len(r) <= limit else r[: limit - 3] + "..."


def _session(p: Problems, session: str, allow_empty: bool = False) -> None:
    if session == "" and allow_empty:
        return
    if session == "":
        p.append("session is empty")
    elif not is_valid_session(session):
        p.append(f"session {_short(session)} is not 1-128 characters of [A-Za-z0-9_.-] "
                 "not starting with '.'")


def _finite(p: Problems, name: str, x: float) -> bool:
    if not math.isfinite(x):
        p.append(f"{name} must be finite, got {x!r}")
        return False
    return True


def _positive(p: Problems, name: str, x: float) -> None:
    if _finite(p, name, x) and x <= 0:
        p.append(f"{name} must be > 0, got {x!r}")


def _nonneg(p: Problems, name: str, x: float) -> None:
    if _finite(p, name, x) and x < 0:
        p.append(f"{name} must be >= 0, got {x!r}")


def _enum(p: Problems, name: str, enum: Any, value: int, allow_zero: bool) -> None:
    if value not in enum.values():
        p.append(f"{name} has unknown value {value}")
    elif value == 0 and not allow_zero:
        p.append(f"{name} is unset ({enum.Name(0)})")


def _pixel(p: Problems, name: str, px: common_pb2.Pixel) -> None:
    _finite(p, f"{name}.u", px.u)
    _finite(p, f"{name}.v", px.v)


def _vec3(p: Problems, name: str, v: common_pb2.Vec3, nonzero: bool = False) -> None:
    ok = all([_finite(p, f"{name}.{c}", getattr(v, c)) for c in "xyz"])
    if ok and nonzero and v.x == 0 and v.y == 0 and v.z == 0:
        p.append(f"{name} must not be the zero vector")


def _intrinsics(p: Problems, name: str, k: common_pb2.Intrinsics) -> None:
    _positive(p, f"{name}.fx", k.fx)
    _positive(p, f"{name}.fy", k.fy)
    _finite(p, f"{name}.cx", k.cx)
    _finite(p, f"{name}.cy", k.cy)
    if k.width == 0 or k.height == 0:
        p.append(f"{name} image size must be positive, got {k.width}x{k.height}")


def _polyline(p: Problems, name: str, pl: common_pb2.Polyline) -> None:
    n = len(pl.points)
    if n < 2:
        p.append(f"{name} needs at least 2 points, got {n}")
    if n > MAX_POLYLINE_POINTS:   # nothing more is read of it
        p.append(f"{name}: at most {MAX_POLYLINE_POINTS} points, got {n}")
        return
    if len(pl.kinds) != max(n - 1, 0):
        p.append(f"{name} has {n} points, so needs {max(n - 1, 0)} segment kinds, "
                 f"got {len(pl.kinds)}")
    for i, px in enumerate(pl.points):
        _pixel(p, f"{name}.points[{i}]", px)
    for i, k in enumerate(pl.kinds):
        _enum(p, f"{name}.kinds[{i}]", common_pb2.SegKind, k, allow_zero=True)


def _height(p: Problems, msg: Message, field: str = "camera_height_m",
            sigma: str = "camera_height_sigma_m", prefix: str = "") -> None:
    if msg.HasField(field):
        _positive(p, prefix + field, getattr(msg, field))
    if msg.HasField(sigma):
        _nonneg(p, prefix + sigma, getattr(msg, sigma))


LENS_SOURCES = ("", "input", "exif", "default")
GRAVITY_SOURCES = ("", "input", "input+image", "image", "level")


def _camera(p: Problems, name: str, c: common_pb2.Camera) -> None:
    """A Camera message: intrinsics (required), gravity, sources and gravity sigma."""
    if not c.HasField("intrinsics"):
        p.append(f"{name}.intrinsics is missing")
    else:
        _intrinsics(p, f"{name}.intrinsics", c.intrinsics)
    if c.HasField("gravity"):
        _vec3(p, f"{name}.gravity", c.gravity, nonzero=True)
    if c.lens_source not in LENS_SOURCES:
        p.append(f"{name}.lens_source must be one of {LENS_SOURCES[1:]}, got {_short(c.lens_source)}")
    if c.gravity_source not in GRAVITY_SOURCES:
        p.append(f"{name}.gravity_source must be one of {GRAVITY_SOURCES[1:]}, "
                 f"got {_short(c.gravity_source)}")
    _nonneg(p, f"{name}.gravity_sigma_rad", c.gravity_sigma_rad)
    for field_name in ("gravity_cov_rad2", "gravity_fit_cov_rad2"):
        cov = getattr(c, field_name)
        if len(cov) not in (0, 4):
            p.append(f"{name}.{field_name} must have 0 or 4 numbers, got {len(cov)}")
        else:
            for i, x in enumerate(cov):
                _finite(p, f"{name}.{field_name}[{i}]", x)
    if len(c.gravity_alternatives) > MAX_GRAVITY_ALTERNATIVES:
        p.append(f"{name}.gravity_alternatives: at most {MAX_GRAVITY_ALTERNATIVES}, got "
                 f"{len(c.gravity_alternatives)}")
    for i, a in enumerate(c.gravity_alternatives[:MAX_GRAVITY_ALTERNATIVES]):
        _vec3(p, f"{name}.gravity_alternatives[{i}].gravity", a.gravity, nonzero=True)
        _positive(p, f"{name}.gravity_alternatives[{i}].ratio", a.ratio)


def _frame(m: frame_pb2.Frame) -> Problems:
    p: Problems = []
    _session(p, m.session)
    if not m.HasField("image"):
        p.append("image is missing")
    else:
        img = m.image
        if not img.data:
            p.append("image.data is empty")
        if img.format not in IMAGE_FORMATS:
            p.append(f"image.format must be one of {', '.join(IMAGE_FORMATS)}, "
                     f"got {_short(img.format)}")
        if img.HasField("timestamp"):
            ns = img.timestamp.seconds * 1_000_000_000 + img.timestamp.nanos
            if ns != m.capture_time_ns:
                p.append(f"image.timestamp ({ns} ns) differs from capture_time_ns "
                         f"({m.capture_time_ns}); leave it unset or equal")
    lens = m.WhichOneof("lens")
    if lens == "intrinsics":
        _intrinsics(p, "intrinsics", m.intrinsics)
    elif lens == "hfov_deg" and not (math.isfinite(m.hfov_deg) and 0 < m.hfov_deg < 180):
        p.append(f"hfov_deg must be in (0, 180) degrees, got {m.hfov_deg!r}")
    if m.HasField("gravity"):
        _vec3(p, "gravity", m.gravity, nonzero=True)
    if m.HasField("gravity_sigma_rad"):
        _nonneg(p, "gravity_sigma_rad", m.gravity_sigma_rad)
    _height(p, m)
    if m.HasField("heading_rad"):
        _finite(p, "heading_rad", m.heading_rad)
    if m.HasField("heading_sigma_rad"):
        s = m.heading_sigma_rad
        if not m.HasField("heading_rad"):
            p.append("heading_sigma_rad is set without heading_rad")
        elif not (math.isfinite(s) and 0 < s <= math.pi / 2):
            p.append(f"heading_sigma_rad must be in (0, pi/2] radians, got {s!r}")
    if m.heading_ref:
        if not m.HasField("heading_rad"):
            p.append("heading_ref is set without heading_rad")
        elif m.heading_ref not in HEADING_REFS:
            p.append(f"heading_ref must be one of {sorted(HEADING_REFS)}, got "
                     f"{m.heading_ref[:20]!r}")
    return p


def _hypothesis_set(m: hypotheses_pb2.HypothesisSet) -> Problems:
    p: Problems = []
    _session(p, m.session)
    if m.width == 0 or m.height == 0:
        p.append(f"image size must be positive, got {m.width}x{m.height}")
    for i, h in enumerate(m.hypotheses):
        name = f"hypotheses[{i}]"
        if h.rank != i + 1:
            p.append(f"{name}.rank must be {i + 1} (best first, 1-based), got {h.rank}")
        _finite(p, f"{name}.score", h.score)
        if _finite(p, f"{name}.support", h.support) and not 0 <= h.support <= 1:
            p.append(f"{name}.support must be in [0, 1], got {h.support!r}")
        _polyline(p, f"{name}.polyline", h.polyline)
    if not m.hypotheses and not m.reason.strip():
        p.append("no hypotheses and no reason: an empty set must say why")
    for k, v in sorted(m.timing_ms.items()):
        _nonneg(p, f"timing_ms[{k!r}]", v)
    if m.HasField("camera"):
        _camera(p, "camera", m.camera)
    if m.HasField("frame_height"):
        _height(p, m.frame_height, prefix="frame_height.")
    _lines(p, m.lines)
    return p


def _lines(p: Problems, lines) -> None:
    """A message's photo lines: 4 finite numbers each, at most ``MAX_LINES``."""
    if len(lines) % 4:
        p.append(f"lines must hold 4 numbers per line (u1, v1, u2, v2), got {len(lines)}")
    if len(lines) > 4 * MAX_LINES:
        p.append(f"lines: at most {MAX_LINES} lines, got {len(lines) // 4}")
    bad = next((i for i, x in enumerate(lines) if not math.isfinite(x)), None)
    if bad is not None:
        p.append(f"lines[{bad}] must be finite, got {lines[bad]!r}")


def _selection(m: selection_pb2.Selection) -> Problems:
    p: Problems = []
    _session(p, m.session)
    if m.rank < 1:
        p.append("rank must be >= 1 (1 = best hypothesis), got 0")
    _enum(p, "by", selection_pb2.SelectedBy, m.by, allow_zero=False)
    _height(p, m)
    return p


def _scene(m: scene_pb2.Scene) -> Problems:
    p: Problems = []
    _session(p, m.session)
    if m.rank < 1:
        p.append("rank must be >= 1, got 0")
    _camera(p, "camera", m.camera)
    _positive(p, "camera_height_m", m.camera_height_m)
    _nonneg(p, "camera_height_sigma_m", m.camera_height_sigma_m)
    _polyline(p, "polyline", m.polyline)
    _lines(p, m.lines)
    return p


def _measure_request(m: measure_pb2.MeasureRequest) -> Problems:
    p: Problems = []
    _session(p, m.session)
    if not m.pixels:
        p.append("pixels is empty: nothing to measure")
    if len(m.pixels) > MAX_MEASURE_PIXELS:
        p.append(f"{len(m.pixels)} pixels in one request, over the limit of {MAX_MEASURE_PIXELS}")
        return p   # each would cost its own problems; the count says enough
    for i, px in enumerate(m.pixels):
        _pixel(p, f"pixels[{i}]", px)
    if m.said and len(m.said) != len(m.pixels):
        p.append(f"said has {len(m.said)} surfaces for {len(m.pixels)} pixels: "
                 "give none or one per pixel")
    for i, s in enumerate(m.said):
        _enum(p, f"said[{i}]", measure_pb2.Surface, s, allow_zero=True)
    return p


def _measure_reply(m: measure_pb2.MeasureReply) -> Problems:
    p: Problems = []
    _session(p, m.session)
    if m.error:
        if m.points or m.distances:
            p.append("a failed request (error set) must carry no points or distances")
        return p
    for i, pt in enumerate(m.points):
        name = f"points[{i}]"
        _pixel(p, f"{name}.pixel", pt.pixel)
        _enum(p, f"{name}.surface", measure_pb2.Surface, pt.surface, allow_zero=True)
        _enum(p, f"{name}.said", measure_pb2.Surface, pt.said, allow_zero=True)
        if pt.error:
            if pt.HasField("xyz") or pt.HasField("sigma_m") or pt.surface or pt.note:
                p.append(f"{name} has an error, so must have no xyz, sigma_m, surface or note")
        else:
            if not pt.HasField("xyz"):
                p.append(f"{name} has neither xyz nor error")
            else:
                _vec3(p, f"{name}.xyz", pt.xyz)
            if pt.surface == measure_pb2.SURFACE_NONE:
                p.append(f"{name} has no error, so needs a surface (FLOOR, WALL or TOP)")
            elif pt.said in (measure_pb2.SURFACE_FLOOR, measure_pb2.SURFACE_WALL,
                             measure_pb2.SURFACE_TOP) and pt.said != pt.surface:
                p.append(f"{name} was said to be on {measure_pb2.Surface.Name(pt.said)} "
                         f"but is on {measure_pb2.Surface.Name(pt.surface)}")
            if pt.surface == measure_pb2.SURFACE_TOP and pt.said != measure_pb2.SURFACE_TOP:
                p.append(f"{name} is on a top, which only a point said to be there is")
            if pt.HasField("sigma_m"):
                _nonneg(p, f"{name}.sigma_m", pt.sigma_m)
    n = len(m.points)
    for i, d in enumerate(m.distances):
        name = f"distances[{i}]"
        if d.a >= n or d.b >= n or d.a == d.b:
            p.append(f"{name} joins points {d.a} and {d.b}: need two different indices "
                     f"below {n}")
        if d.error:
            if d.HasField("distance_m") or d.HasField("sigma_m"):
                p.append(f"{name} has an error, so must have no distance_m or sigma_m")
        else:
            if not d.HasField("distance_m"):
                p.append(f"{name} has neither distance_m nor error")
            else:
                _nonneg(p, f"{name}.distance_m", d.distance_m)
            if d.HasField("sigma_m"):
                _nonneg(p, f"{name}.sigma_m", d.sigma_m)
    return p


_MOTION_VALUES = ("x_m", "z_m", "yaw_rad")
_MOTION_SIGMAS = ("sigma_x_m", "sigma_z_m", "sigma_yaw_rad")


def _motion(m: motion_pb2.Motion) -> Problems:
    p: Problems = []
    _session(p, m.session)
    if m.index_a == m.index_b:
        p.append(f"index_a and index_b are both {m.index_a}: a motion needs two photos")
    present = [f for f in _MOTION_VALUES + _MOTION_SIGMAS if m.HasField(f)]
    if m.error:
        if present:
            p.append(f"a failed motion (error set) must carry no numbers, has {', '.join(present)}")
    else:
        missing = [f for f in _MOTION_VALUES if not m.HasField(f)]
        if missing:
            p.append(f"{', '.join(missing)} missing and no error: a motion carries "
                     "x_m, z_m and yaw_rad, or an error")
        for f in present:
            (_nonneg if f.startswith("sigma") else _finite)(p, f, getattr(m, f))
    if m.inliers > m.matches:
        p.append(f"inliers ({m.inliers}) exceed matches ({m.matches})")
    _motion_evidence(p, m)
    return p


def _motion_evidence(p: Problems, m: motion_pb2.Motion) -> None:
    """score, layout and alternatives: bounded, finite, none on a failed motion."""
    if m.error and (m.HasField("score") or m.HasField("layout") or len(m.alternatives)
                    or m.HasField("appearance")):
        p.append("a failed motion (error set) must carry no score, layout, alternatives or "
                 "appearance")
    if m.HasField("score"):
        _finite(p, "score", m.score)
    if m.HasField("appearance") and _finite(p, "appearance", m.appearance) \
            and abs(m.appearance) > 1.0:
        p.append(f"appearance is a correlation in [-1, 1], got {m.appearance!r}")
    if len(m.alternatives) > MAX_ALTERNATIVES:
        p.append(f"alternatives: at most {MAX_ALTERNATIVES}, got {len(m.alternatives)}")
    for i, a in enumerate(m.alternatives[:MAX_ALTERNATIVES]):
        for f in _MOTION_VALUES + _MOTION_SIGMAS:
            (_nonneg if f.startswith("sigma") else _finite)(p, f"alternatives[{i}].{f}",
                                                            getattr(a, f))
        if a.HasField("score"):
            _finite(p, f"alternatives[{i}].score", a.score)
    if m.HasField("layout"):
        lay = m.layout
        if lay.rank_a < 1 or lay.rank_b < 1:
            p.append(f"layout ranks start at 1, got ({lay.rank_a}, {lay.rank_b})")
        if lay.HasField("rms_m"):
            _nonneg(p, "layout.rms_m", lay.rms_m)
        for name in ("walls", "corners"):
            if len(getattr(lay, name)) > MAX_LAYOUT_PAIRS:
                p.append(f"layout.{name}: at most {MAX_LAYOUT_PAIRS}, "
                         f"got {len(getattr(lay, name))}")
    if m.HasField("gravity"):
        _motion_gravity(p, m.gravity)


#: How a Motion's photos' gravities were settled (``MotionGravity.status``).
GRAVITY_STATUSES = ("agreed", "disagree", "unlinked")


def _motion_gravity(p: Problems, g: motion_pb2.MotionGravity) -> None:
    if g.status not in GRAVITY_STATUSES:
        p.append(f"gravity.status {g.status!r} is not one of {GRAVITY_STATUSES}")
    if g.HasField("angle_rad"):
        _nonneg(p, "gravity.angle_rad", g.angle_rad)
    for f in ("sigma_a_rad", "sigma_b_rad"):
        if g.HasField(f):
            _nonneg(p, f"gravity.{f}", getattr(g, f))
    for f in ("gravity_a", "gravity_b"):
        if g.HasField(f):
            _vec3(p, f"gravity.{f}", getattr(g, f), nonzero=True)


def _pose_fields(p: Problems, m: motion_pb2.Pose, prefix: str = "") -> None:
    for f in _MOTION_VALUES:
        _finite(p, prefix + f, getattr(m, f))
    for f in _MOTION_SIGMAS:
        if m.HasField(f):
            _nonneg(p, prefix + f, getattr(m, f))


def _pose(m: motion_pb2.Pose) -> Problems:
    p: Problems = []
    _session(p, m.session)
    _pose_fields(p, m)
    return p


def _trajectory(m: motion_pb2.Trajectory) -> Problems:
    p: Problems = []
    _session(p, m.session)
    last = -1
    for i, pose in enumerate(m.poses):
        name = f"poses[{i}]"
        if pose.schema not in ("", motion_pb2.Pose.DESCRIPTOR.full_name):
            p.append(f"{name}.schema must be empty or findme.v1.Pose, got {_short(pose.schema)}")
        if pose.session not in ("", m.session):
            p.append(f"{name}.session {_short(pose.session)} differs from the trajectory's")
        if pose.index <= last:
            p.append(f"{name}.index {pose.index} out of order (after {last}): poses are "
                     "sorted by index, each at most once")
        last = pose.index
        _pose_fields(p, pose, f"{name}.")
    return p


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


def _error(m: status_pb2.Error) -> Problems:
    p: Problems = []
    _session(p, m.session, allow_empty=True)
    _enum(p, "code", status_pb2.ErrorCode, m.code, allow_zero=False)
    if not m.message.strip():
        p.append("message is empty: say what went wrong")
    return p


def _service_status(m: status_pb2.ServiceStatus) -> Problems:
    p: Problems = []
    if not m.service:
        p.append("service is empty")
    if not m.instance:
        p.append("instance is empty")
    return p


VALIDATORS: dict[str, Callable[[Any], Problems]] = {
    cls.DESCRIPTOR.full_name: fn for cls, fn in [
        (frame_pb2.Frame, _frame),
        (hypotheses_pb2.HypothesisSet, _hypothesis_set),
        (selection_pb2.Selection, _selection),
        (scene_pb2.Scene, _scene),
        (measure_pb2.MeasureRequest, _measure_request),
        (measure_pb2.MeasureReply, _measure_reply),
        (motion_pb2.Motion, _motion),
        (motion_pb2.Pose, _pose),
        (motion_pb2.Trajectory, _trajectory),
        (plan_pb2.Plan, _plan),
        (status_pb2.Error, _error),
        (status_pb2.ServiceStatus, _service_status),
    ]
}
