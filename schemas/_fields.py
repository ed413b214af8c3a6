"""Checks of the fields bus messages share (ids, numbers, pixels, cameras, polylines,
lines) and the limits they are held to; the per-type checks (``_photo``, ``_motion``,
``_plan``) call them. Each check appends problems naming the field and the offending
value to a list. No geometry, no findme_core.
"""

from __future__ import annotations

import math
import re
from typing import Any

from google.protobuf.message import Message

from .v1 import common_pb2

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


def _lines(p: Problems, lines) -> None:
    """A message's photo lines: 4 finite numbers each, at most ``MAX_LINES``."""
    if len(lines) % 4:
        p.append(f"lines must hold 4 numbers per line (u1, v1, u2, v2), got {len(lines)}")
    if len(lines) > 4 * MAX_LINES:
        p.append(f"lines: at most {MAX_LINES} lines, got {len(lines) // 4}")
    bad = next((i for i, x in enumerate(lines) if not math.isfinite(x)), None)
    if bad is not None:
        p.append(f"lines[{bad}] must be finite, got {lines[bad]!r}")
