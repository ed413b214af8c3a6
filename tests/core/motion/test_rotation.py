"""The rotation between two photos' cameras from their matches alone (one spot)."""

from __future__ import annotations

import math

import numpy as np

from findme_core.geometry.camera import Camera
from findme_core.motion import rotation
from findme_core.motion.features import Matches

CAM = Camera(500.0, 500.0, 320.0, 240.0, 640, 480)


def _rot(axis, deg):
    a = np.asarray(axis, float) / np.linalg.norm(axis)
    K = np.array([[0, -a[2], a[1]], [a[2], 0, -a[0]], [-a[1], a[0], 0]])
    t = math.radians(deg)
    return np.eye(3) + math.sin(t) * K + (1 - math.cos(t)) * K @ K


def test_the_batched_kabsch_is_the_single_one_sample_by_sample():
    rng = np.random.default_rng(1)
    a = rng.normal(size=(50, 2, 3))
    b = rng.normal(size=(50, 2, 3))
    a /= np.linalg.norm(a, axis=2, keepdims=True)
    b /= np.linalg.norm(b, axis=2, keepdims=True)
    batch = rotation.kabsch_batch(a, b)
    for k in range(50):
        np.testing.assert_allclose(batch[k], rotation.kabsch(a[k], b[k]), atol=1e-12)
        assert np.linalg.det(batch[k]) > 0          # a rotation, never a reflection


def test_a_pure_rotation_is_recovered_from_matches_with_outliers():
    rng = np.random.default_rng(2)
    M = _rot((0.2, 1.0, 0.1), 30.0)                       # b_A = M b_B
    pts_b = np.column_stack([rng.uniform(-1, 1, 150), rng.uniform(-0.8, 0.8, 150), np.ones(150)])
    pts_a = pts_b @ M.T
    keep = pts_a[:, 2] > 0.3
    ua = pts_a[keep, :2] / pts_a[keep, 2:] * 500 + (320, 240)
    ub = pts_b[keep, :2] / pts_b[keep, 2:] * 500 + (320, 240)
    ub[::4] = rng.uniform((0, 0), (640, 480), size=(len(ub[::4]), 2))      # a quarter wrong
    n = len(ua)
    m = Matches(ua, ub, np.arange(n), np.arange(n), np.full(n, 0.5), n, n)
    got, k = rotation.pure_rotation(m, CAM, CAM, 2.0, 15, 0.3)
    assert k >= int(0.7 * n)
    assert np.degrees(np.arccos(min((np.trace(got.T @ M) - 1) / 2, 1.0))) < 0.05
    again = rotation.pure_rotation(m, CAM, CAM, 2.0, 15, 0.3)
    assert np.array_equal(again[0], got)                   # seeded: the same every time


def test_collinear_bearings_fix_no_rotation():
    ua = np.tile([[320.0, 240.0]], (20, 1))                # every match the same direction
    m = Matches(ua, ua.copy(), np.arange(20), np.arange(20), np.full(20, 0.5), 20, 20)
    assert rotation.pure_rotation(m, CAM, CAM, 2.0, 15, 0.3) is None
