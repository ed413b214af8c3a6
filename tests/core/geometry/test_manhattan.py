"""Manhattan frame search and refinement (findme_core.geometry.manhattan) on exact synthetic lines:
3D segments along the three directions of a known frame, projected by a known camera."""

import math

import cv2
import numpy as np
import pytest

from findme_core.geometry.camera import Camera
from findme_core.geometry.manhattan import (LineSet, frame_of, pitch_roll_deg, refine, residuals,
                                            score_frames, search, tilt_grid)
from findme_core.single.vanishing import _line_set, _segment_coef

CAM = Camera.from_hfov(70.0, 640, 480)
PRIOR = ((-25.0, 60.0), (-40.0, 40.0))


def true_frame(pitch_deg=25.0, roll_deg=3.0, yaw_deg=20.0):
    """R = [h1, g, h2] in camera coordinates for a camera pitched down and rolled."""
    g = tilt_grid((pitch_deg, pitch_deg), (roll_deg, roll_deg), 1.0)[0]
    return frame_of(g, math.radians(yaw_deg))


def project(P):
    p = (CAM.K @ P.T).T
    return p[:, :2] / p[:, 2:]


def manhattan_lines(R, n_per_dir=(6, 8, 8), seed=0, extra=None):
    """Segments along the columns of R at random places 2-6 m in front of the camera,
    clipped to those whose both ends fall in the image; returns (segments (N, 4), column of
    each)."""
    rng = np.random.default_rng(seed)
    segs, cols = [], []
    for c, n in zip((1, 0, 2), (n_per_dir[0], n_per_dir[1], n_per_dir[2])):
        d = R[:, c]
        k = 0
        while k < n:
            centre = np.array([rng.uniform(-2, 2), rng.uniform(-1.0, 1.5), rng.uniform(2, 6)])
            a, b = centre - 0.6 * d, centre + 0.6 * d
            if a[2] < 0.5 or b[2] < 0.5:
                continue
            ab = project(np.array([a, b]))
            if not ((ab >= 0).all() and (ab[:, 0] < 640).all() and (ab[:, 1] < 480).all()):
                continue
            if np.hypot(*(ab[1] - ab[0])) < 40:
                continue
            segs.append(ab.ravel())
            cols.append(c)
            k += 1
    return np.array(segs), np.array(cols)


def line_set(segs):
    return _line_set(segs, _segment_coef(segs), np.hypot(*(segs[:, 2:] - segs[:, :2]).T), CAM.K)


def angle_deg(a, b):
    return math.degrees(math.acos(float(np.clip(abs(a @ b), -1, 1))))


def test_residuals_zero_for_lines_through_their_vanishing_point():
    R = true_frame()
    segs, cols = manhattan_lines(R)
    L = line_set(segs)
    r = residuals(L, (CAM.K @ R).T)                       # (N, 3)
    assert np.all(r[np.arange(len(L)), cols] < 1e-9)
    # and they do not point at the other two
    others = np.array([[c2 for c2 in range(3) if c2 != c] for c in cols])
    assert np.all(r[np.arange(len(L))[:, None], others] > 1e-3)


def test_a_point_on_the_segment_is_no_vanishing_point():
    """Lines meeting at a room corner meet there: a corner is not a vanishing point."""
    L = line_set(np.array([[100.0, 300.0, 300.0, 300.0]]))
    on = residuals(L, np.array([[200.0, 300.0, 1.0], [310.0, 300.0, 1.0], [2000.0, 300.0, 1.0]]))
    assert on[0, 0] == 1.0 and on[0, 1] == 1.0 and on[0, 2] < 1e-12
    # undefined (the point is the midpoint itself, or the null vector): 1.0, never an inlier
    assert residuals(L, np.zeros((1, 3)))[0, 0] == 1.0


def test_analytic_jacobian_matches_finite_differences():
    from findme_core.geometry.manhattan import _jacobian
    R = true_frame(30.0, -4.0, 35.0)
    segs, cols = manhattan_lines(R, seed=3)
    L = line_set(segs)
    D = R[:, cols].T
    e0, J = _jacobian(L.mid, L.normal, CAM.K, D)
    for k in range(3):
        w = np.zeros(3)
        w[k] = 1e-6
        Rp, _ = cv2.Rodrigues(w.reshape(3, 1))
        Rm, _ = cv2.Rodrigues(-w.reshape(3, 1))
        num = (_jacobian(L.mid, L.normal, CAM.K, (Rp @ D.T).T)[0]
               - _jacobian(L.mid, L.normal, CAM.K, (Rm @ D.T).T)[0]) / 2e-6
        assert np.allclose(J[:, k], num, atol=1e-6 * (1 + np.abs(num).max()))
    assert np.allclose(e0, 0.0, atol=1e-9)


def test_refine_returns_the_true_frame_from_two_degrees_off():
    R = true_frame()
    segs, _ = manhattan_lines(R, seed=1)
    L = line_set(segs)
    off, _ = cv2.Rodrigues(np.radians([1.2, -0.8, 1.3]).reshape(3, 1))
    R2, cov, masks = refine(L, CAM.K, off @ R, 1.5)
    assert masks.sum() == len(L)
    assert angle_deg(R2[:, 1], R[:, 1]) < 1e-4
    assert cov is not None and cov.shape == (3, 3) and np.all(np.linalg.eigvalsh(cov) >= 0)


def test_search_finds_the_frame_over_the_prior():
    for pitch, roll, yaw in ((25.0, 3.0, 20.0), (5.0, -6.0, -30.0), (45.0, 10.0, 5.0)):
        R = true_frame(pitch, roll, yaw)
        L = line_set(manhattan_lines(R, seed=int(pitch))[0])
        found = search(L, CAM.K, *PRIOR, coarse_lines=60, inlier_deg=1.5, peaks=8,
                       coarse_deg=3.0, fine_deg=1.0, best=3)
        assert 1 <= len(found) <= 3
        assert angle_deg(found[0][:, 1], R[:, 1]) < 1.5          # then refine does the rest
        assert np.allclose(pitch_roll_deg(refine(L, CAM.K, found[0], 1.5)[0][:, 1]),
                           (pitch, roll), atol=1e-3)
        s, a = score_frames(L, CAM.K, R[:, 1][None], 1.5)
        # the azimuth is the centre of the modal 1.5 deg bin: the horizontal lines are off
        # by at most half a bin, the verticals not at all
        assert s[0] > 0.75 * L.w.sum()
        h1 = frame_of(R[:, 1], float(a[0]))[:, 0]
        assert min(angle_deg(h1, R[:, 0]), angle_deg(h1, R[:, 2])) <= 0.75 + 1e-6


def test_vertical_only_lines_are_never_horizontal_inliers():
    R = true_frame()
    segs, cols = manhattan_lines(R, seed=2)
    L = line_set(segs).only_vertical(cols != 1)                  # horizontals barred
    _, _, masks = refine(L, CAM.K, R, 1.5)
    assert masks[0].sum() == 0 and masks[2].sum() == 0 and masks[1].sum() == (cols == 1).sum()
    s, _ = score_frames(L, CAM.K, R[:, 1][None], 1.5)
    assert s[0] == pytest.approx(L.w[cols == 1].sum(), rel=1e-4)


def test_degenerate_inputs():
    empty = LineSet(np.zeros((0, 2)), np.zeros((0, 2)), np.zeros((0, 3)), np.zeros(0), np.zeros(0))
    assert search(empty, CAM.K, *PRIOR, 60, 1.5) == []
    R, cov, masks = refine(empty, CAM.K, true_frame(), 1.5)
    assert cov is None and masks.shape == (3, 0)
    # three lines cannot fix a rotation and its residual scale: no covariance
    segs, _ = manhattan_lines(true_frame(), (1, 1, 1), seed=4)
    assert refine(line_set(segs), CAM.K, true_frame(), 1.5)[1] is None
