"""``plan/wall_sigmas``: the outline's 1-sigmas without the joint refinement, on outlines
whose lines and offsets are set here, so the exact answer is known."""

import math

import numpy as np
import pytest

from findme_core.plan import polygon, wall_sigmas


def _outline(normals, offsets, line, vertices):
    k = len(offsets)
    lines = polygon.Lines(np.asarray(normals, float), np.asarray(offsets, float),
                          np.tile([-10.0, 10.0], (k, 1)))
    out = polygon.Outline(np.asarray(vertices, float), np.asarray(line, int),
                          np.ones(len(vertices), bool), lines)
    return out, lines


def test_a_right_angled_corner_moves_with_each_walls_offset_along_its_normal():
    # a 4 x 3 m rectangle: walls x = 0, z = 0, x = 4, z = 3 (normals along the axes)
    out, lines = _outline([[1, 0], [0, 1], [1, 0], [0, 1]], [0, 0, 4, 3], [0, 1, 2, 3],
                          [[0, 3], [0, 0], [4, 0], [4, 3]])
    sig_d = np.array([0.01, 0.02, 0.03, 0.04])
    s = wall_sigmas.corner_sigmas(out, lines, sig_d, 0.0)
    # vertex k is where wall k - 1 meets wall k: vertex 1 (0, 0) on x = 0 (0.01) and z = 0
    np.testing.assert_allclose(s, [[0.01, 0.04], [0.01, 0.02], [0.03, 0.02], [0.03, 0.04]])


def test_the_camera_height_scales_a_corner_along_its_distance():
    out, lines = _outline([[1, 0], [0, 1], [1, 0], [0, 1]], [0, 0, 4, 3], [0, 1, 2, 3],
                          [[0, 3], [0, 0], [4, 0], [4, 3]])
    s = wall_sigmas.corner_sigmas(out, lines, np.zeros(4), 0.02)
    np.testing.assert_allclose(s, 0.02 * np.abs(out.vertices))


def test_an_oblique_corner_and_a_nearly_parallel_one():
    # lines x = 0 and one turned 30 deg from it: the corner slides 1 / sin 30 = 2x its offset
    # along the first line
    t = math.radians(30.0)
    n2 = [math.cos(t), math.sin(t)]
    out, lines = _outline([[1, 0], n2, [1, 0]], [0, 0, 1], [0, 1, 2],
                          [[0, 5], [0, 0], [1, 5]])
    s = wall_sigmas.corner_sigmas(out, lines, np.array([0.0, 0.01, 0.0]), 0.0)
    assert s[1] == pytest.approx([0.0, 0.01 / math.sin(t)])
    # 2 deg apart: taken as meeting at MIN_SIN, not sliding without bound
    t = math.radians(2.0)
    out, lines = _outline([[1, 0], [math.cos(t), math.sin(t)], [1, 0]], [0, 0, 1], [0, 1, 2],
                          [[0, 5], [0, 0], [1, 5]])
    s = wall_sigmas.corner_sigmas(out, lines, np.array([0.0, 0.01, 0.0]), 0.0)
    assert np.hypot(*s[1]) == pytest.approx(0.01 / wall_sigmas.MIN_SIN, rel=1e-6)


def test_a_corner_off_any_wall_line_is_only_bounded_by_the_raster():
    out, lines = _outline([[1, 0], [0, 1]], [0, 0], [0, -1, 1], [[0, 3], [0, 0], [4, 0]])
    s = wall_sigmas.corner_sigmas(out, lines, np.array([0.01, 0.02]), 0.0)
    np.testing.assert_allclose(s[1:], wall_sigmas.RASTER_M)   # both touch the edge off a line
    assert s[0] == pytest.approx([0.01, 0.02])
