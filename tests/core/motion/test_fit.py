"""``motion_fit.common_depth_sigma``: the error a baseline's length shares with the depths of
the lifted points it rests on (the points of one photo move together)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from findme_core.motion.fit import common_depth_sigma


def _points(n, dist, rel, rng):
    """n points at ``dist`` metres in random level directions, with relative sigma ``rel``."""
    az = rng.uniform(-1.0, 1.0, n)
    pts = np.column_stack([dist * np.sin(az), rng.uniform(-1, 1, n), dist * np.cos(az)])
    return pts, rel * np.linalg.norm(pts, axis=1)


def test_one_photos_points_do_not_average_their_common_error_away():
    rng = np.random.default_rng(0)
    for n in (1, 10, 200):
        assert common_depth_sigma([_points(n, 3.0, 0.07, rng), (np.zeros((0, 3)), np.zeros(0))]) \
            == pytest.approx(0.07)


def test_two_photos_with_equal_weight_combine_as_independent_errors():
    rng = np.random.default_rng(1)
    got = common_depth_sigma([_points(20, 3.0, 0.05, rng), _points(20, 5.0, 0.05, rng)])
    assert got == pytest.approx(0.05 / math.sqrt(2))


def test_the_photo_whose_points_weigh_more_sets_the_error():
    """A photo with near, precise points (2 %) and one with far, loose ones (20 %): the
    length rests on the first; the second adds (w_B e_B)^2, 100x less weight each."""
    rng = np.random.default_rng(2)
    a, b = _points(10, 1.5, 0.02, rng), _points(10, 6.0, 0.2, rng)
    wa, wb = 10 / 0.02 ** 2, 10 / 0.2 ** 2
    want = math.hypot(wa * 0.02, wb * 0.2) / (wa + wb)
    assert common_depth_sigma([a, b]) == pytest.approx(want)
    assert 0.0198 < common_depth_sigma([a, b]) < 0.021


def test_weighted_mean_within_a_photo():
    """Relative sigmas 0.1 and 0.2 in one photo: weights 100 and 25, mean (10 + 5) / 125."""
    pts = np.array([[0.0, 0.0, 2.0], [0.0, 0.0, 4.0]])
    assert common_depth_sigma([(pts, np.array([0.2, 0.8]))]) == pytest.approx(0.12)


def test_no_lifted_point_no_term():
    empty = (np.zeros((0, 3)), np.zeros(0))
    assert common_depth_sigma([empty, empty]) == 0.0
    assert common_depth_sigma([]) == 0.0
