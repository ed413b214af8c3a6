"""Structural checks of the photo's messages: Frame, HypothesisSet, Selection, Scene,
MeasureRequest and MeasureReply (``_validate.VALIDATORS``)."""

from __future__ import annotations

import math

from ._fields import (HEADING_REFS, IMAGE_FORMATS, MAX_MEASURE_PIXELS, Problems, _camera, _enum,
                      _finite, _height, _intrinsics, _lines, _nonneg, _pixel, _polyline,
                      _positive, _session, _short, _vec3)
from .v1 import frame_pb2, hypotheses_pb2, measure_pb2, scene_pb2, selection_pb2


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
