"""Structural checks of the motion's messages: Motion (its alternatives, layout evidence
and gravity), Pose and Trajectory (``_validate.VALIDATORS``)."""

from __future__ import annotations

from ._fields import (MAX_ALTERNATIVES, MAX_LAYOUT_PAIRS, Problems, _finite, _nonneg, _session,
                      _short, _vec3)
from .v1 import motion_pb2

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
