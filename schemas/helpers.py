"""Small pure helpers between numpy arrays / planar poses and message parts.

Only numpy and protobuf: converters from findme_core objects belong in the services.
"""

from __future__ import annotations

import math

import numpy as np
from foxglove_schemas_protobuf.FrameTransform_pb2 import FrameTransform
from foxglove_schemas_protobuf.PoseInFrame_pb2 import PoseInFrame
from foxglove_schemas_protobuf.Quaternion_pb2 import Quaternion
from google.protobuf.timestamp_pb2 import Timestamp

from findme_core.errors import SchemaError

from .v1 import common_pb2, measure_pb2, motion_pb2

_NS = 1_000_000_000


def pixels_to_msg(pixels) -> list[common_pb2.Pixel]:
    """(N, 2) array-like of (u, v) -> list of Pixel (for ``msg.pixels.extend``)."""
    a = np.asarray(pixels, dtype=float)
    if a.size == 0:
        return []
    if a.ndim != 2 or a.shape[1] != 2 or not np.all(np.isfinite(a)):
        raise SchemaError(f"pixels must be an (N, 2) array of finite (u, v), got shape {a.shape}")
    return [common_pb2.Pixel(u=float(u), v=float(v)) for u, v in a]


def msg_to_pixels(pixels) -> np.ndarray:
    """Iterable of Pixel -> (N, 2) float64 array."""
    return np.array([(p.u, p.v) for p in pixels], dtype=float).reshape(-1, 2)


_SURFACES = {None: measure_pb2.SURFACE_NONE, "floor": measure_pb2.SURFACE_FLOOR,
             "wall": measure_pb2.SURFACE_WALL, "top": measure_pb2.SURFACE_TOP}
_SURFACE_NAMES = {v: k for k, v in _SURFACES.items()}


def surface_value(name: str | None) -> int:
    """"floor", "wall", "top" or None -> its Surface value (SURFACE_NONE for None)."""
    if not (name is None or isinstance(name, str) and name in _SURFACES):
        raise SchemaError(f"a surface must be floor, wall, top or None, got {name!r}")
    return _SURFACES[name]


def surface_name(value: int) -> str | None:
    """A Surface value -> "floor", "wall", "top" or None (SURFACE_NONE, or a value not
    known)."""
    return _SURFACE_NAMES.get(value)


def surfaces_to_msg(said) -> list[int]:
    """Per pixel "floor", "wall" or None ("as the boundary says") -> Surface values for
    ``MeasureRequest.said.extend``: [] when ``said`` is None or says nothing (the
    request's "nothing said")."""
    return [surface_value(s) for s in said] if said and any(said) else []


def msg_to_surfaces(said) -> list[str | None] | None:
    """Surface values -> per pixel "floor", "wall" or None; None when none is said (as
    ``Scene.locate`` takes it)."""
    out = [surface_name(s) for s in said]
    return out if any(out) else None


def polyline_to_msg(points, kinds=None) -> common_pb2.Polyline:
    """(M, 2) vertices and (M - 1,) segment kinds -> Polyline.

    ``kinds`` are SegKind numbers (findme_core.single.search.SegKind values are the same numbers);
    None means every segment is a WALL.
    """
    pts = np.asarray(points, dtype=float)
    if pts.ndim != 2 or pts.shape[1] != 2 or len(pts) < 2 or not np.all(np.isfinite(pts)):
        raise SchemaError(f"a polyline needs an (M >= 2, 2) array of finite (u, v), "
                          f"got shape {pts.shape}")
    if kinds is None:
        k = np.full(len(pts) - 1, common_pb2.SEG_KIND_WALL, dtype=int)
    else:
        k = np.asarray(kinds).astype(int).reshape(-1)
    if len(k) != len(pts) - 1:
        raise SchemaError(f"a polyline of {len(pts)} points needs {len(pts) - 1} segment kinds, "
                          f"got {len(k)}")
    bad = sorted(set(k.tolist()) - set(common_pb2.SegKind.values()))
    if bad:
        raise SchemaError(f"unknown segment kind(s) {bad}; known: "
                          f"{dict(common_pb2.SegKind.items())}")
    return common_pb2.Polyline(points=pixels_to_msg(pts), kinds=k.tolist())


def msg_to_polyline(msg: common_pb2.Polyline) -> tuple[np.ndarray, np.ndarray]:
    """Polyline -> ((M, 2) float64 vertices, (M - 1,) int64 SegKind numbers)."""
    return msg_to_pixels(msg.points), np.array(list(msg.kinds), dtype=np.int64)


def vec3_to_msg(v) -> common_pb2.Vec3:
    """3 numbers -> Vec3."""
    a = np.asarray(v, dtype=float).reshape(-1)
    if a.shape != (3,):
        raise SchemaError(f"a Vec3 needs 3 numbers, got shape {a.shape}")
    return common_pb2.Vec3(x=float(a[0]), y=float(a[1]), z=float(a[2]))


def msg_to_vec3(msg: common_pb2.Vec3) -> np.ndarray:
    """Vec3 -> (3,) float64."""
    return np.array([msg.x, msg.y, msg.z], dtype=float)


def ns_to_timestamp(ns: int) -> Timestamp:
    """Integer nanoseconds since the epoch -> google.protobuf.Timestamp (as in Foxglove types)."""
    s, n = divmod(int(ns), _NS)
    return Timestamp(seconds=s, nanos=n)


def timestamp_to_ns(ts: Timestamp) -> int:
    """google.protobuf.Timestamp -> integer nanoseconds since the epoch."""
    return ts.seconds * _NS + ts.nanos


def level_frame_id(session: str, index: int) -> str:
    """Foxglove frame name of the level frame of photo ``index``: "<session>/level/<n>"."""
    return f"{session}/level/{index}"


def yaw_quaternion(yaw_rad: float) -> Quaternion:
    """The rotation R_y(yaw) about the level frame's y axis (down) as a quaternion:
    > 0 turns +z (forward) toward +x (right)."""
    h = 0.5 * float(yaw_rad)
    return Quaternion(x=0.0, y=math.sin(h), z=0.0, w=math.cos(h))


def pose_to_foxglove(pose: motion_pb2.Pose, session: str | None = None) -> PoseInFrame:
    """A planar Pose -> foxglove.PoseInFrame in the level frame of photo 0.

    The pose is of photo n's level frame (camera centre at the same height, y down), so
    position = (x_m, 0, z_m) and the orientation is a yaw about y.
    """
    s = pose.session if session is None else session
    out = PoseInFrame(timestamp=ns_to_timestamp(pose.time_ns), frame_id=level_frame_id(s, 0))
    out.pose.position.x, out.pose.position.y, out.pose.position.z = pose.x_m, 0.0, pose.z_m
    out.pose.orientation.CopyFrom(yaw_quaternion(pose.yaw_rad))
    return out


def pose_to_frame_transform(pose: motion_pb2.Pose, session: str | None = None,
                            parent_frame_id: str | None = None,
                            child_frame_id: str | None = None) -> FrameTransform:
    """A planar Pose -> foxglove.FrameTransform from the level frame of photo 0 (parent)
    to the level frame of photo n (child); defaults from ``level_frame_id``."""
    s = pose.session if session is None else session
    out = FrameTransform(
        timestamp=ns_to_timestamp(pose.time_ns),
        parent_frame_id=parent_frame_id or level_frame_id(s, 0),
        child_frame_id=child_frame_id or level_frame_id(s, pose.index))
    out.translation.x, out.translation.y, out.translation.z = pose.x_m, 0.0, pose.z_m
    out.rotation.CopyFrom(yaw_quaternion(pose.yaw_rad))
    return out
