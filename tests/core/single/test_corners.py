"""Vertical wall corners found by their shading crease (findme_core.single.corners) in images made
here: two walls whose brightness bends along a known line above two floor lines."""

import math

import numpy as np
import pytest

from findme_core.single.corners import CornerParams, corner_verticals, floor_corners

CORNER = np.array([300.0, 330.0])
# the two baseboards leave the corner down-left and down-right
BASEBOARDS = np.array([[40.0, 430.0, CORNER[0], CORNER[1]],
                       [CORNER[0], CORNER[1], 620.0, 400.0]])


def walls(theta_deg: float, crease: float = 15.0, noise: float = 1.0, seed: int = 0):
    """(480, 640) uint8: walls above the baseboards whose shading slope bends by ``crease``
    grey levels per 100 px along the line from CORNER at ``theta_deg`` from the image's up
    direction (positive to the right; 15 makes a crease ~1.2 grey levels deep over +-4 px,
    as faint as the dev photos' corners), a darker floor below, and pixel noise."""
    H, W = 480, 640
    v, u = np.mgrid[0:H, 0:W].astype(float)
    t = math.radians(theta_deg)
    n = np.array([math.cos(t), math.sin(t)])          # normal of the corner line
    d = (u - CORNER[0]) * n[0] + (v - CORNER[1]) * n[1]
    img = 150.0 - crease / 100.0 * np.abs(d) + 0.02 * d   # bent, and not symmetric
    # floor below the two baseboard lines
    for x1, y1, x2, y2 in BASEBOARDS:
        below = (v - y1) * (x2 - x1) - (u - x1) * (y2 - y1) > 0
        inside = (u >= min(x1, x2)) & (u <= max(x1, x2))
        img[below & inside] = 90.0
    img += np.random.default_rng(seed).normal(0.0, noise, img.shape)
    return np.clip(img, 0, 255).astype(np.uint8)


def found_angle(segs):
    d = segs[:, 2:] - segs[:, :2]
    return np.degrees(np.arctan2(d[:, 0], -d[:, 1]))


@pytest.mark.parametrize("theta", [-12.0, 0.0, 7.5, 21.0])
def test_the_crease_above_a_floor_corner_is_found(theta):
    segs, t = corner_verticals(walls(theta), BASEBOARDS, np.array([300.0, 320.0]))
    assert len(segs) == 1 and t[0] >= CornerParams().min_t
    assert np.allclose(segs[0, :2], CORNER, atol=1.0)            # it rises from the corner
    assert abs(found_angle(segs)[0] - theta) < 1.0
    assert np.hypot(*(segs[0, 2:] - segs[0, :2])) >= CornerParams().min_len_px


def test_no_crease_no_corner_edge():
    segs, t = corner_verticals(walls(5.0, crease=0.0), BASEBOARDS, np.array([300.0, 320.0]))
    assert len(segs) == 0 and len(t) == 0


def test_floor_corners_are_l_junctions_not_crossings():
    c, pairs = floor_corners(BASEBOARDS, np.array([300.0, 320.0]), 640, 480)
    assert np.allclose(c, [CORNER], atol=1e-6) and pairs.tolist() == [[0, 1]]
    crossing = np.array([[100.0, 300.0, 500.0, 300.0], [300.0, 100.0, 300.0, 450.0]])
    assert len(floor_corners(crossing, np.array([400.0, 350.0]), 640, 480)[0]) == 0
    parallel = np.array([[100.0, 300.0, 500.0, 300.0], [100.0, 320.0, 500.0, 320.0]])
    assert len(floor_corners(parallel, np.array([400.0, 400.0]), 640, 480)[0]) == 0


def test_degenerate_inputs():
    img = walls(0.0)
    assert corner_verticals(img, np.zeros((0, 4)), np.zeros(0))[0].shape == (0, 4)
    assert corner_verticals(img, BASEBOARDS[:1], np.array([300.0]))[0].shape == (0, 4)
    # a corner at the top border: no room for a ray
    top = np.array([[40.0, 60.0, 300.0, 2.0], [300.0, 2.0, 620.0, 50.0]])
    assert len(corner_verticals(img, top, np.array([300.0, 300.0]))[0]) == 0
