"""One-sided lifting (findme_core.motion.one_sided) and near-duplicate matches
(features.distinct) on exact rendered geometry: photo B stands close to a wall and sees no
floor at all (no hypothesis, no layout); the matches lifted in A alone, placed in B by their
height, give B's exact pose; and copies of one match count once."""

from __future__ import annotations

import math

import numpy as np
import pytest

from findme_core.motion import one_sided as motion_lifted
from findme_core.geometry.camera import Camera
from findme_core.motion.features import Lifted, Matches, distinct
from findme_core.motion.methods import MotionParams, estimate
from findme_core.motion.model import MotionInputs
from findme_core.geometry.planar import bearings
from findme_core.synth.render import Pose, planar_motion
from tests.core.layout_rooms import exact_orientation

# A sees the far wall (Z = 3.5) and the floor from 5 m; B, level, stands 0.9 m from that wall:
# a level 70-deg view sees floor only beyond 2.75 m, so B sees the wall alone
POSE_A = Pose(0.0, -1.5, 1.4, 10.0, 20.0)
POSE_B = Pose(0.8, 2.6, 1.4, -5.0)
FIT_ONLY = MotionParams(findme_scale_sigma=0.0, findme_direction_sigma_deg=0.0,
                        findme_yaw_sigma_deg=0.0, findme_position_sigma_m=0.0)


def wall_pair(n=60, seed=0, pose_a=POSE_A, pose_b=POSE_B):
    """Matches of points on the wall Z = 3.5 seen by both photos, their exact level-frame
    3D in each photo, and the cameras."""
    rng = np.random.default_rng(seed)
    height = rng.uniform(1.0, 1.3, n) + 0.5 * (rng.random(n) < 0.5)   # off B's horizon
    X = np.column_stack([rng.uniform(0.45, 1.15, n), -height, np.full(n, 3.5)])
    px, lev, cams = [], [], []
    for pose in (pose_a, pose_b):
        cam = Camera.from_hfov(70.0, 640, 480, gravity=pose.gravity_cam)
        uv, front = cam.project_cam((X - pose.centre_world) @ pose.R_cam_from_world.T)
        assert front.all() and (uv > 0).all() and (uv[:, 0] < 639).all() and (uv[:, 1] < 479).all()
        px.append(uv), cams.append(cam)
        lev.append((X - pose.centre_world) @ pose.R_level_from_world.T)
    m = Matches(px[0], px[1], np.arange(n), np.arange(n), np.linspace(0.3, 0.8, n), n, n)
    return m, cams, lev


def _lifted(P, sigma=0.01):
    return Lifted(P.copy(), np.full(len(P), sigma), np.zeros(len(P), bool))


def _inputs(m, cams, lev, side):
    a, b = bearings(cams[0], m.ua), bearings(cams[1], m.ub)
    none = Lifted.empty(len(m))
    la, lb = (_lifted(lev[0]), none) if side == "A" else (none, _lifted(lev[1]))
    return MotionInputs(a, b, la, lb, 0.0, POSE_A.height, 1.0 / cams[0].fx)


@pytest.mark.parametrize("side", ["A", "B"])
def test_one_lifted_match_fixes_the_translation_at_a_known_yaw(side):
    m, cams, lev = wall_pair()
    P = _inputs(m, cams, lev, side)
    corr = motion_lifted.correspondences(P)
    pa, pb, sig, idx = corr
    # the points the other photo sees within 3 deg of its horizon are left out (B stands
    # 0.9 m from the wall, A 5 m)
    other = P.b if side == "A" else P.a
    assert sorted(idx) == np.flatnonzero(np.abs(other[:, 1]) > math.sin(math.radians(3))).tolist()
    assert len(idx) >= 20
    # each correspondence is the same wall point in both level frames
    assert np.allclose(pa, lev[0][idx][:, [0, 2]], atol=1e-9)
    assert np.allclose(pb, lev[1][idx][:, [0, 2]], atol=1e-9)
    assert (sig > 0).all()
    x, z, yaw = planar_motion(POSE_A, POSE_B)
    t = motion_lifted.at_yaw(corr, math.radians(yaw))
    assert np.allclose(t[0], [x, z], atol=1e-9)


def test_points_at_the_horizon_or_on_the_wrong_side_are_left_out():
    m, cams, lev = wall_pair(n=4)
    P = _inputs(m, cams, lev, "A")
    b = P.b.copy()
    b[0] = [0.6, 0.0, 0.8]                              # on the horizon: any depth fits
    b[1] = [0.0, -np.sign(P.la.points[1, 1]) * 0.6, 0.8]   # the wrong side of the horizon
    corr = motion_lifted.correspondences(MotionInputs(P.a, b, P.la, P.lb, 0.0, 1.4, P.pix))
    assert sorted(corr[3]) == [2, 3]
    none = Lifted.empty(4)
    empty = motion_lifted.correspondences(MotionInputs(P.a, P.b, none, none, 0.0, 1.4, P.pix))
    assert [len(c) for c in empty] == [0, 0, 0, 0]
    assert motion_lifted.at_yaw(empty, 0.3).shape == (0, 2)


def test_a_photo_that_sees_only_a_wall_is_placed_by_the_other_photo_s_lift():
    """B has no hypothesis and no layout; 40 % of the matches are wrong."""
    m, (ca, cb), lev = wall_pair(n=80)
    rng = np.random.default_rng(3)
    wrong = rng.choice(len(m), 32, replace=False)
    ub = m.ub.copy()
    ub[wrong] = ub[rng.permutation(wrong)] + rng.normal(0, 20, (32, 2))
    m = Matches(m.ua, np.clip(ub, 1, 478), m.ia, m.ib, m.ratio, m.n_a, m.n_b)

    def lift_a(idx):
        out = Lifted.empty(len(m))
        out.points[idx], out.sigma[idx] = lev[0][idx], 0.01
        return out
    # the points lie on one plane, so the epipolar geometry alone is degenerate; the yaw
    # comes from the room's orientation (its lines), the translation from A's lift
    r = estimate(m, ca, cb, 1.4, 1.4, lift_a, None, "findme", FIT_ONLY,
                 orientations=(exact_orientation(POSE_A), exact_orientation(POSE_B)))
    x, z, yaw = planar_motion(POSE_A, POSE_B)
    # A's points are 5 m away: a 1 deg gravity error (the estimator's prior) is 0.3 m there
    assert r.x == pytest.approx(x, abs=0.05) and r.z == pytest.approx(z, abs=0.05)
    assert abs(r.z - z) < 2 * r.sigma_z
    assert math.degrees(r.yaw) == pytest.approx(yaw, abs=0.5)
    right = np.ones(len(m), bool)
    right[wrong] = False
    assert r.inliers[right].mean() > 0.85   # (wrong ones on the same plane may fit too)


def test_copies_of_a_match_count_once():
    ua = np.array([[100.0, 100.0], [101.0, 100.5], [300.0, 200.0], [102.5, 99.0], [400.0, 50.0]])
    ub = ua + [[20.0, 0.0]]
    ub[4] = [100.0, 100.0]                     # near match 0 in B only: not a copy
    m = Matches(ua, ub, np.arange(5), np.arange(5), np.array([0.6, 0.5, 0.7, 0.8, 0.4]), 5, 5)
    keep, rep = distinct(m, 4.0)
    assert keep.tolist() == [1, 2, 4]          # the most distinctive copy stands for 0, 1, 3
    assert keep[rep].tolist() == [1, 1, 2, 1, 4]
    keep, rep = distinct(m, 0.5)
    assert keep.tolist() == [0, 1, 2, 3, 4] and rep.tolist() == [0, 1, 2, 3, 4]
    empty = distinct(m.subset(np.zeros(5, bool)), 4.0)
    assert [len(x) for x in empty] == [0, 0]


def test_the_copies_of_an_inlier_are_inliers():
    """Every match twice (two pyramid levels): the answer is unchanged, and each copy's
    inlier flag is its original's."""
    m, (ca, cb), lev = wall_pair(n=40)
    n = len(m)
    two = Matches(np.vstack([m.ua, m.ua + 0.7]), np.vstack([m.ub, m.ub - 0.5]),
                  np.r_[m.ia, m.ia], np.r_[m.ib, m.ib], np.r_[m.ratio, m.ratio + 0.05], n, n)
    P = np.vstack([lev[0], lev[0]])

    def lift_a(idx):
        out = Lifted.empty(2 * n)
        out.points[idx], out.sigma[idx] = P[idx], 0.01
        return out
    orient = (exact_orientation(POSE_A), exact_orientation(POSE_B))
    r = estimate(two, ca, cb, 1.4, 1.4, lift_a, None, "findme", FIT_ONLY, orientations=orient)
    one = estimate(m, ca, cb, 1.4, 1.4, lambda i: Lifted(*(f[:n] for f in (
        lift_a(i).points, lift_a(i).sigma, lift_a(i).floor))), None, "findme", FIT_ONLY,
        orientations=orient)
    x, z, _ = planar_motion(POSE_A, POSE_B)
    assert r.x == pytest.approx(x, abs=0.05) and r.z == pytest.approx(z, abs=0.05)
    assert (r.x, r.z, r.yaw) == pytest.approx((one.x, one.z, one.yaw), abs=1e-6)
    assert r.inliers.shape == (2 * n,) and (r.inliers[:n] == r.inliers[n:]).all()
