"""numpy and Foxglove helpers."""

from __future__ import annotations

import math

import numpy as np
import pytest

import schemas as S
from findme_core.errors import SchemaError


def test_polyline_roundtrip():
    pts = np.array([[0.0, 352.5], [210.25, 301.0], [639.0, 371.75]])
    kinds = np.array([S.SEG_KIND_STEP, S.SEG_KIND_OPEN])
    p, k = S.msg_to_polyline(S.polyline_to_msg(pts, kinds))
    assert p.dtype == np.float64 and p.shape == (3, 2) and np.array_equal(p, pts)
    assert k.dtype == np.int64 and k.tolist() == [1, 2]


def test_polyline_default_kinds_are_walls():
    _, k = S.msg_to_polyline(S.polyline_to_msg([(0, 1), (5, 2), (9, 3)]))
    assert k.tolist() == [S.SEG_KIND_WALL] * 2


def test_polyline_accepts_core_seg_kinds():
    from findme_core.single.search import SegKind

    msg = S.polyline_to_msg([(0, 1), (5, 2), (9, 3)], [SegKind.STEP, SegKind.NONE])
    assert list(msg.kinds) == [S.SEG_KIND_STEP, S.SEG_KIND_NONE]


@pytest.mark.parametrize("points,kinds,fragment", [
    ([(0, 1)], None, "M >= 2"),
    ([(0, 1, 2), (3, 4, 5)], None, "(M >= 2, 2)"),
    ([(0, math.nan), (1, 2)], None, "finite"),
    ([(0, 1), (1, 2)], [0, 0], "needs 1 segment kinds, got 2"),
    ([(0, 1), (1, 2)], [7], "unknown segment kind(s) [7]"),
])
def test_polyline_errors(points, kinds, fragment):
    with pytest.raises(SchemaError) as info:
        S.polyline_to_msg(points, kinds)
    assert fragment in str(info.value)


def test_pixels_and_vec3():
    px = [[1.5, 2.5], [3.0, 4.0]]
    assert S.msg_to_pixels(S.pixels_to_msg(px)).tolist() == px
    assert S.pixels_to_msg([]) == [] and S.msg_to_pixels([]).shape == (0, 2)
    assert S.msg_to_vec3(S.vec3_to_msg((0.1, 0.9, -0.2))).tolist() == [0.1, 0.9, -0.2]
    with pytest.raises(SchemaError):
        S.vec3_to_msg((1, 2))
    with pytest.raises(SchemaError):
        S.pixels_to_msg([(1, 2, 3)])


def test_timestamps():
    for ns in (0, 1, 999_999_999, 1_714_557_600_123_456_789):
        ts = S.ns_to_timestamp(ns)
        assert 0 <= ts.nanos < 1_000_000_000
        assert S.timestamp_to_ns(ts) == ns


def _rotate(q, v):
    """Rotate v by unit quaternion q (x, y, z, w)."""
    u = np.array([q.x, q.y, q.z])
    v = np.asarray(v, dtype=float)
    return v + 2 * q.w * np.cross(u, v) + 2 * np.cross(u, np.cross(u, v))


def test_yaw_quaternion_turns_forward_to_the_right():
    yaw = math.radians(30)
    q = S.yaw_quaternion(yaw)
    # R_y(yaw) of the planar convention: forward (+z) goes toward +x (right) for yaw > 0.
    R = np.array([[math.cos(yaw), 0, math.sin(yaw)], [0, 1, 0],
                  [-math.sin(yaw), 0, math.cos(yaw)]])
    for v in np.eye(3):
        assert np.allclose(_rotate(q, v), R @ v)
    assert _rotate(q, (0, 0, 1))[0] > 0


def test_pose_to_foxglove():
    pose = S.Pose(session="s1", index=4, x_m=1.5, z_m=5.25, yaw_rad=0.13, time_ns=2_500_000_001)
    pif = S.pose_to_foxglove(pose)
    assert pif.frame_id == "s1/level/0"
    assert (pif.pose.position.x, pif.pose.position.y, pif.pose.position.z) == (1.5, 0.0, 5.25)
    assert math.isclose(2 * math.atan2(pif.pose.orientation.y, pif.pose.orientation.w), 0.13)
    assert (pif.timestamp.seconds, pif.timestamp.nanos) == (2, 500_000_001)
    tf = S.pose_to_frame_transform(pose)
    assert (tf.parent_frame_id, tf.child_frame_id) == ("s1/level/0", "s1/level/4")
    assert (tf.translation.x, tf.translation.z) == (1.5, 5.25)
    assert tf.rotation == pif.pose.orientation
    tf2 = S.pose_to_frame_transform(pose, parent_frame_id="world", child_frame_id="cam")
    assert (tf2.parent_frame_id, tf2.child_frame_id) == ("world", "cam")
