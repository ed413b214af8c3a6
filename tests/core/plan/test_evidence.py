"""The placement evidence (findme_core.plan.evidence): motions given either way round, and the
motion term peaking at the pose the motion says, the feature term flat near the epipolar
plane (or MSAC)."""

from dataclasses import replace

import numpy as np
import pytest

from findme_core.geometry import planar
from findme_core.plan import evidence, fuse

A = np.array([0.5, -0.2, 0.3])      # a placed photo's pose (x, z, yaw)
B = np.array([1.5, 1.0, -0.4])      # the block photo's true pose


@pytest.mark.parametrize("given_from_block", [False, True])
def test_a_motion_given_either_way_is_the_block_photos_pose_in_the_placed_ones(given_from_block):
    yaw, t = fuse.relative(A, B)
    link = (fuse.Link(0, 1, float(yaw), 0.01, tuple(t)) if not given_from_block else
            fuse.Link(1, 0, *(lambda y, u: (float(y), 0.01, tuple(u)))(*fuse.relative(B, A))))
    ((i, j, y, u),) = evidence.oriented([link], members=[1])
    assert (i, j) == (0, 1)
    np.testing.assert_allclose(fuse.compose(A, y, u), B, atol=1e-12)


def test_links_without_translation_and_within_one_block_are_not_motions():
    turn = fuse.Link(0, 1, 0.5, 0.01)                       # a rotation-only link
    inside = fuse.Link(1, 2, 0.1, 0.01, (0.3, 0.2))         # both photos in the block
    assert list(evidence.oriented([turn, inside], members=[1, 2])) == []


def test_the_motion_term_peaks_at_the_pose_the_motion_says():
    yaw, t = fuse.relative(A, B)
    poses = np.array([A, [np.nan] * 3])
    cands = np.array([B, B + (0.3, 0.0, 0.0), B + (0.0, 0.0, np.radians(6))])
    s = evidence.motion_score([fuse.Link(0, 1, float(yaw), 0.01, tuple(t))], poses,
                              np.zeros(2), [1], cands, fuse.FuseParams())
    assert s[0] == pytest.approx(fuse.FuseParams().motion_weight)
    assert s[0] > s[1] > 0 and s[0] > s[2] > 0


def _matches(n=60, seed=0):
    """Level bearings (a, b) of n points seen by photos at poses A and B (planar motion)."""
    yaw, t = fuse.relative(A, B)
    t3 = np.array([t[0], 0.0, t[1]])
    rng = np.random.default_rng(seed)
    X = np.column_stack([rng.uniform(-2, 2, n), rng.uniform(-1, 1, n), rng.uniform(3, 6, n)])
    XB = (X - t3) @ planar.rot_y(yaw)          # X_A = R_y(yaw) X_B + t
    a, b = X / np.linalg.norm(X, axis=1)[:, None], XB / np.linalg.norm(XB, axis=1)[:, None]
    assert np.abs(planar.epipolar_residuals(yaw, t3, a, b)).max() < 1e-9
    return {(0, 1): (a, b)}


@pytest.mark.parametrize("fade", [24.0, 0.0])
def test_the_feature_term_is_flat_within_its_pixels_or_msac(fade):
    params = replace(fuse.FuseParams(), feature_fade_px=fade)
    poses = np.array([A, [np.nan] * 3])
    cands = np.array([B, B + (0.0, 0.0, np.radians(0.2)), B + (0.0, 0.0, np.radians(5.0)),
                      B + (0.0, 0.0, np.radians(20.0))])
    s = evidence.feature_score(_matches(), poses, np.zeros(2), [1], cands, params)
    assert s[0] == pytest.approx(60 * params.feature_weight)     # every match, in full
    if fade > params.feature_px:   # 0.2 deg (~2 px) is inside the flat part; 5 deg fades
        assert s[1] == pytest.approx(s[0]) and 0 < s[2] < s[0]
    else:                          # MSAC: any residual costs
        assert s[2] < s[1] < s[0]
    assert s[3] == 0.0             # 20 deg: no match near its epipolar plane


def _turn_matches(yaw, m=200, seed=3):
    """Bearings of M points seen from one place by two photos turned ``yaw`` apart, the
    same point in both: a = R_y(yaw) b."""
    rng = np.random.default_rng(seed)
    a = rng.normal(size=(m, 3)) * (0.5, 0.2, 0.0) + (0.0, 0.1, 1.0)
    a /= np.linalg.norm(a, axis=1, keepdims=True)
    b = planar.rot_y(yaw).T @ a.T
    return a, b.T


def test_at_the_placed_photos_place_the_feature_term_is_a_turn():
    # a block at the placed photo's position (its candidate from the other spot's walls
    # turned half round, say): the epipolar plane of a nil baseline holds every match of
    # the right turn whatever its direction, and random matches by the thousand
    params = fuse.FuseParams()
    poses = np.array([A, [np.nan] * 3])
    a, b = _turn_matches(0.7)
    here = np.array([[A[0], A[1], A[2] + 0.7], [A[0] + 1e-13, A[1], A[2] + 0.7],
                     [A[0], A[1], A[2] + 1.7], [A[0], A[1] + 1e-13, A[2] - 2.4]])
    s = evidence.feature_score({(0, 1): (a, b)}, poses, np.zeros(2), [1], here, params)
    assert s[0] == pytest.approx(200 * params.feature_weight)   # the right turn: all of them
    assert s[1] == pytest.approx(s[0])                           # a last bit of baseline: alike
    assert s[2] == 0.0 and s[3] == 0.0                           # turned 1 rad, 3.1 rad: none
    rng = np.random.default_rng(5)
    ra = rng.normal(size=(3000, 3)) * (0.5, 0.3, 0.0) + (0.0, 0.0, 1.0)
    rb = rng.normal(size=(3000, 3)) * (0.5, 0.3, 0.0) + (0.0, 0.0, 1.0)
    ra /= np.linalg.norm(ra, axis=1, keepdims=True)
    rb /= np.linalg.norm(rb, axis=1, keepdims=True)
    s = evidence.feature_score({(0, 1): (ra, rb)}, poses, np.zeros(2), [1], here, params)
    assert np.all(s < 0.01 * 3000 * params.feature_weight)     # chance matches: < 1 % count
    # away from the place (0.1 m and more) the epipolar term is used as before
    moved = np.array([[A[0] + 0.1, A[1], A[2] + 0.7]])
    t2 = evidence._in_frame(A, moved)[1]
    r = np.abs(planar.epipolar_residuals(np.array([0.7]), np.array([[t2[0, 0], 0.0, t2[0, 1]]]),
                                         a, b))
    assert evidence.feature_score({(0, 1): (a, b)}, poses, np.zeros(2), [1], moved, params)[0] \
        > 0 and r.max() < 1e-9   # the true turn's points lie on any epipolar plane of t


def test_turn_residuals_are_the_angle_from_a_pure_turn():
    a, b = _turn_matches(-0.4, m=5)
    np.testing.assert_allclose(planar.turn_residuals(np.array([-0.4]), a, b), 0.0, atol=1e-7)
    r = planar.turn_residuals(np.array([-0.4 + 0.01, 0.0]), a, b)
    assert r.shape == (2, 5)
    # turned 0.01 rad about the vertical: a bearing at elevation e moves cos(e) x 0.01
    np.testing.assert_allclose(r[0], 0.01 * np.hypot(a[:, 0], a[:, 2]), rtol=1e-3)
