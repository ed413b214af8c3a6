"""The placement evidence (findme_core.evidence): motions given either way round, and the
motion term peaking at the pose the motion says."""

import numpy as np
import pytest

from findme_core import evidence, fuse

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
