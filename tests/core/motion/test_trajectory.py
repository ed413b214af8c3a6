"""Tests of findme_core.motion.trajectory: chaining planar motions (exact against synthetic poses),
covariance growth, and the TUM export round trip."""

from __future__ import annotations

import math

import numpy as np
import pytest

from findme_core.errors import InputError
from findme_core.motion.methods import PlanarMotion
from findme_core.synth.render import Pose, planar_motion
from findme_core.motion.trajectory import TUM_HEADER, PlanarPose, chain, compose, from_tum, to_tum

WALK = [Pose(0.0, 0.0, 1.4, 0.0), Pose(0.3, 0.8, 1.4, 20.0, 15.0), Pose(1.1, 1.2, 1.4, 75.0),
        Pose(1.6, 0.4, 1.4, 160.0, 10.0, 3.0), Pose(0.9, -0.5, 1.4, -150.0)]


def _motions(poses):
    return [tuple(map(float, (*planar_motion(a, b)[:2], math.radians(planar_motion(a, b)[2]))))
            for a, b in zip(poses[:-1], poses[1:])]


def test_chain_of_successive_motions_gives_each_pose_in_the_first_level_frame():
    poses = chain(_motions(WALK))
    assert len(poses) == len(WALK) and poses[0] == PlanarPose(0.0, 0.0, 0.0, 0.0)
    for p, truth in zip(poses, WALK):
        x, z, yaw = planar_motion(WALK[0], truth)
        assert (p.x, p.z) == (pytest.approx(x, abs=1e-12), pytest.approx(z, abs=1e-12))
        assert math.degrees(p.yaw) == pytest.approx(yaw, abs=1e-9) and p.y == 0.0
        assert np.allclose(p.cov, 0.0)


def test_pose_matrix_composes_like_the_motions():
    m = _motions(WALK)
    poses = chain(m)
    T = np.eye(4)
    for x, z, yaw in m:
        c, s = math.cos(yaw), math.sin(yaw)
        T = T @ np.array([[c, 0, s, x], [0, 1, 0, 0], [-s, 0, c, z], [0, 0, 0, 1.0]])
    assert np.allclose(poses[-1].matrix(), T, atol=1e-12)


def test_vertical_offsets_accumulate_and_covariance_grows():
    pm = PlanarMotion(0.0, 1.0, math.radians(10), 0.05, 0.02, 0.03, math.radians(1.0),
                      np.ones(10, bool), 10, "findme")
    poses = chain([pm] * 4)
    assert poses[-1].y == pytest.approx(0.2)
    sx = [math.sqrt(p.cov[0, 0]) for p in poses]
    assert sx[0] == 0.0 and all(b > a for a, b in zip(sx[1:], sx[2:]))
    # the heading error makes the lateral error grow faster than the motion's own sigma
    assert sx[-1] > 2 * 0.02
    assert np.allclose(poses[-1].cov, poses[-1].cov.T) and np.all(np.linalg.eigvalsh(poses[-1].cov) >= 0)


def test_tum_export_round_trips():
    poses = chain(_motions(WALK))
    stamps = [1_700_000_000_123_456_789 + k * 333_333_333 for k in range(len(poses))]
    text = to_tum(poses, stamps)
    assert text.startswith(TUM_HEADER) and all(l.startswith("#") for l in TUM_HEADER.splitlines())
    body = [l for l in text.splitlines() if not l.startswith("#")]
    assert len(body) == len(poses) and all(len(l.split()) == 8 for l in body)
    back_stamps, back = from_tum(text)
    assert back_stamps == stamps
    for p, q in zip(poses, back):
        assert np.allclose([p.x, p.y, p.z], [q.x, q.y, q.z], atol=1e-9)
        assert math.isclose(math.cos(p.yaw - q.yaw), 1.0, abs_tol=1e-12)


def test_tum_quaternion_is_the_rotation_about_the_vertical():
    """qx qy qz qw of R_y(yaw): B's forward axis (0, 0, 1) ends up at (sin, 0, cos) in the
    session frame, i.e. turned right toward +x for yaw > 0 (world_from_camera)."""
    yaw = math.radians(30)
    qx, qy, qz, qw = PlanarPose(0, 0, 0, yaw).quaternion()
    v = np.array([0.0, 0.0, 1.0])
    u = np.array([qx, qy, qz])
    rotated = v + 2 * qw * np.cross(u, v) + 2 * np.cross(u, np.cross(u, v))
    assert np.allclose(rotated, [math.sin(yaw), 0, math.cos(yaw)], atol=1e-12)


@pytest.mark.parametrize("bad", ["0 1 2 3", "0 1 2 3 0 0.2 0 0.98 9", "x 1 2 3 0 0 0 1",
                                 "0 1 2 3 0.7071 0 0 0.7071"])
def test_from_tum_rejects_malformed_lines(bad):
    with pytest.raises(InputError, match="line 1"):
        from_tum(bad)


def test_bad_inputs_are_input_errors():
    with pytest.raises(InputError, match="timestamps"):
        to_tum([PlanarPose(0, 0, 0, 0)], [])
    with pytest.raises(InputError, match="non-negative"):
        to_tum([PlanarPose(0, 0, 0, 0)], [-1])
    with pytest.raises(InputError, match="finite"):
        compose(PlanarPose(0, 0, 0, 0), float("nan"), 0.0, 0.0)
    with pytest.raises(InputError, match="x, z, yaw"):
        chain([(1.0, 2.0)])
