"""The placement evidence (findme_core.plan.evidence): motions given either way round, and the
motion term peaking at the pose the motion says, the feature term flat near the epipolar
plane (or MSAC)."""

from dataclasses import replace

import numpy as np
import pytest

from findme_core.plan import evidence, fuse
from findme_core.geometry import planar

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
