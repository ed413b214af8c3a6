"""Two plain photos of one spot agree on gravity: an unsure gravity from one photo's lines is
completed by the other photo's through their matches, and the motion comes out right;
photos that cannot link, or that disagree beyond their sigmas, keep their own and say so."""

from __future__ import annotations

import math

import cv2
import numpy as np
import pytest

from findme_core.errors import MotionError
from findme_core.geometry.camera import Camera
from findme_core.geometry.manhattan import gravity_of
from findme_core.motion import pair, pair_gravity
from findme_core.motion.photo_lines import photo_lines
from findme_core.motion.features import Matches
from findme_core.single import gravity_alternatives as alt
from findme_core.single.photo import hypothesize_without_gravity
from findme_core.synth.render import render
from findme_core.synth.room import Pose, Room

H = 1.4


@pytest.fixture(scope="module")
def turn():
    """Two photos turning 45 deg at one spot, 30 deg down, wood floor, no gravity given, as
    a camera app saves them (JPEG, quality 95): [(image, camera without gravity, true
    gravity, gravity estimate, hypotheses)]."""
    out = []
    for yaw in (0.0, 45.0):
        v = render(Room.rectangle(5.0, 4.0), Pose(0.3, -0.2, H, yaw, 30.0, 0.0), 640, 480,
                   hfov_deg=70.0, supersample=1)
        image = cv2.imdecode(cv2.imencode(".jpg", v.image, [cv2.IMWRITE_JPEG_QUALITY, 95])[1],
                             cv2.IMREAD_COLOR)
        cam = Camera(v.camera.fx, v.camera.fy, v.camera.cx, v.camera.cy, 640, 480)
        hs, est = hypothesize_without_gravity(image, cam, max_n=1, camera_height=H)
        out.append((image, cam, v.camera.gravity, est, hs))
    return out


def _photos(turn, sigmas=None):
    photos = []
    for k, (image, cam, _, est, hs) in enumerate(turn):
        s = est.sigma if sigmas is None else sigmas[k]
        photos.append(pair.prepare(image, cam.with_gravity(est.vector), H, hs.hypotheses, 1,
                                   photo_lines(hs, image), gravity_sigma=s))
    return photos


def test_an_unsure_gravity_is_completed_by_the_other_photo_and_the_motion_is_right(turn):
    own = [alt.angle_deg(est.vector, g) for _, _, g, est, _ in turn]
    # alone, the second photo's lines leave its gravity far off, and it says it is unsure
    assert own[0] < 1.0 and own[1] > 10.0 and math.degrees(turn[1][3].sigma) > 10.0
    pa, pb = _photos(turn)
    res = pair.motion_photos(pa, pb)["findme"]
    g = res.gravity
    assert g.status == "agreed" and math.degrees(g.angle) > 10.0
    assert alt.angle_deg(g.gravity_b, turn[1][2]) < 1.0          # now right
    assert np.array_equal(g.gravity_a, alt.down(pa.camera.gravity))   # the sure one kept
    assert math.degrees(g.sigma_b) < pair_gravity.UNSURE_GRAVITY_DEG
    m = res.motion
    assert abs(math.degrees(m.yaw) - 45.0) < 1.0 and math.hypot(m.x, m.z) < 0.05


def test_without_the_check_the_same_photos_give_a_wrong_motion(turn):
    """What the check is for: the same photos, the unsure gravity taken as it is."""
    pa, pb = _photos(turn)
    pa, pb = (pair.relift(p, p.camera.gravity, None) for p in (pa, pb))   # sigma None: given
    res = pair.motion_photos(pa, pb)["findme"]
    assert res.gravity is None
    assert abs(math.degrees(res.motion.yaw) - 45.0) > 5.0 or \
        math.hypot(res.motion.x, res.motion.z) > 0.3


def test_sure_photos_are_not_checked(turn):
    pa, pb = _photos(turn, sigmas=(math.radians(1.0), math.radians(1.0)))
    out = pair.agreed_gravity(pa, pb, None)
    assert out == (pa, pb, None)


def test_relift_under_its_own_gravity_changes_nothing(turn):
    pa, _ = _photos(turn)
    again = pair.relift(pa, pa.camera.gravity, pa.gravity_sigma)
    assert again.features is pa.features
    assert [lay.range.tolist() for lay in again.layouts] == [lay.range.tolist() for lay in pa.layouts]
    np.testing.assert_array_equal(again.surface.points, pa.surface.points)
    np.testing.assert_array_equal(again.scene.polyline, pa.scene.polyline)


# ---- degenerate cases, on synthetic matches where the answer is known --------------------

CAM = Camera(500.0, 500.0, 320.0, 240.0, 640, 480)


def _matches(points_a, R_ab, t_ab) -> Matches:
    """Matches of 3D points (N, 3) in A's camera frame seen by B = R_ab^T (X - t_ab)."""
    pb = (points_a - t_ab) @ R_ab
    ua = points_a[:, :2] / points_a[:, 2:] * 500.0 + (320.0, 240.0)
    ub = pb[:, :2] / pb[:, 2:] * 500.0 + (320.0, 240.0)
    n = len(ua)
    return Matches(ua, ub, np.arange(n), np.arange(n), np.full(n, 0.5), n, n)


def _points(n=120, seed=0):
    rng = np.random.default_rng(seed)
    return np.column_stack([rng.uniform(-2, 2, n), rng.uniform(-1.5, 1.5, n), rng.uniform(1.5, 6, n)])


def _yaw(deg):
    c, s = math.cos(math.radians(deg)), math.sin(math.radians(deg))
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


def test_photos_from_two_places_are_unlinked_and_keep_their_own():
    g = gravity_of(20.0, 0.0)
    m = _matches(_points(), _yaw(10.0), np.array([1.0, 0.0, 0.5]))    # parallax
    ca, cb = CAM.with_gravity(g), CAM.with_gravity(gravity_of(35.0, 5.0))
    out = pair_gravity.agree(m, ca, cb, math.radians(1.0), math.radians(20.0))
    assert out.status == "unlinked" and out.inliers == 0 and math.isnan(out.angle)
    assert np.allclose(out.gravity_b, cb.gravity) and out.sigma_b == math.radians(20.0)
    assert "no rotation" in out.reason


def test_too_few_matches_are_unlinked():
    m = _matches(_points(10), _yaw(10.0), np.zeros(3))
    out = pair_gravity.agree(m, CAM, CAM, math.radians(1.0), math.radians(20.0))
    assert out.status == "unlinked"


def test_two_sure_gravities_far_apart_disagree_and_keep_their_own():
    """A pure 10 deg turn; A's gravity right, B's 15 deg off, both claiming 1 deg."""
    R = _yaw(10.0)
    m = _matches(_points(), R, np.zeros(3))
    true_a = gravity_of(25.0, 0.0)
    wrong_b = gravity_of(40.0, 0.0)      # B's true gravity is R^T true_a (pitch 25 in B too)
    ca, cb = CAM.with_gravity(true_a), CAM.with_gravity(wrong_b)
    out = pair_gravity.agree(m, ca, cb, math.radians(1.0), math.radians(1.0))
    assert out.status == "disagree" and 14.0 < math.degrees(out.angle) < 16.0
    assert np.allclose(out.gravity_a, true_a) and np.allclose(out.gravity_b, wrong_b)
    assert "one of them is wrong" in out.reason


def test_an_unsure_photo_takes_the_carried_gravity_and_a_sure_one_keeps_its_own():
    R = _yaw(30.0)
    m = _matches(_points(), R, np.zeros(3))
    true_a = gravity_of(25.0, 3.0)
    true_b = R.T @ true_a
    off_b = gravity_of(10.0, -15.0)
    out = pair_gravity.agree(m, CAM.with_gravity(true_a), CAM.with_gravity(off_b),
                             math.radians(1.0), math.radians(30.0))
    assert out.status == "agreed" and out.inliers == 120
    assert np.allclose(out.gravity_a, true_a)                       # sure: kept
    assert alt.angle_deg(out.gravity_b, true_b) < 0.5                # unsure: completed
    link = math.radians(pair_gravity.PairGravityParams().link_sigma_deg)
    assert link < out.sigma_b < math.radians(3.0)


def test_combine_two_equal_estimates_gives_their_bisector_and_a_smaller_sigma():
    a, b = gravity_of(10.0, 0.0), gravity_of(20.0, 0.0)
    g, s = pair_gravity.combine(a, 0.02, b, 0.02)
    assert alt.angle_deg(g, gravity_of(15.0, 0.0)) < 1e-6
    assert s == pytest.approx(0.02 / math.sqrt(2.0))


def test_a_photo_assumed_level_takes_the_other_photos_gravity():
    """No evidence at all (infinite sigma): the other photo's gravity, carried, is its."""
    R = _yaw(-20.0)
    m = _matches(_points(seed=3), R, np.zeros(3))
    true_a = gravity_of(15.0, -4.0)
    out = pair_gravity.agree(m, CAM.with_gravity(true_a), CAM.with_gravity(gravity_of(0.0, 0.0)),
                             math.radians(1.0), math.inf)
    assert out.status == "agreed"
    assert alt.angle_deg(out.gravity_b, R.T @ true_a) < 1e-6 and math.isfinite(out.sigma_b)
    both = pair_gravity.agree(m, CAM, CAM, math.inf, math.inf)
    assert both.status == "unlinked" and "neither" in both.reason


def test_an_unsure_photos_alternative_can_be_the_one_the_pair_agrees_on():
    """B's own estimate is 40 deg off, beyond 3 of its 10 deg sigma, but its lines also
    support the true direction (an alternative): the pair agrees on that one, as a spot's
    photos vote with their alternatives; without the alternative they disagree."""
    R = _yaw(45.0)
    m = _matches(_points(seed=5), R, np.zeros(3))
    true_a = gravity_of(30.0, 0.0)
    true_b = R.T @ true_a
    ca, cb = CAM.with_gravity(true_a), CAM.with_gravity(gravity_of(-10.0, 0.0))
    alone = pair_gravity.agree(m, ca, cb, math.radians(1.0), math.radians(10.0))
    assert alone.status == "disagree" and math.degrees(alone.angle) > 30.0
    near_truth = gravity_of(*[x + 1.0 for x in alt_pitch_roll(true_b)])
    out = pair_gravity.agree(m, ca, cb, math.radians(1.0), math.radians(10.0),
                             alternatives=((), (near_truth, gravity_of(0.0, 25.0))))
    assert out.status == "agreed" and alt.angle_deg(out.gravity_b, true_b) < 1.0
    assert math.degrees(out.angle) > 30.0          # the own estimates were that far apart


def alt_pitch_roll(g):
    from findme_core.geometry.manhattan import pitch_roll_deg
    return pitch_roll_deg(alt.down(g))


def test_a_phones_gravity_wins_over_a_photos_lines_that_disagree_with_it():
    """A's gravity from the phone's sensors, B's from its lines 40 deg off at a claimed 10:
    beyond 3 sigma, and the sensor is the one to believe: B takes A's, carried."""
    R = _yaw(45.0)
    m = _matches(_points(seed=7), R, np.zeros(3))
    true_a = gravity_of(30.0, 0.0)
    ca, cb = CAM.with_gravity(true_a), CAM.with_gravity(gravity_of(-10.0, 0.0))
    out = pair_gravity.agree(m, ca, cb, math.radians(0.5), math.radians(10.0),
                             given=(True, False))
    assert out.status == "agreed" and alt.angle_deg(out.gravity_b, R.T @ true_a) < 1e-6
    assert np.array_equal(out.gravity_a, true_a) and math.degrees(out.angle) > 30.0
    both_lines = pair_gravity.agree(m, ca, cb, math.radians(0.5), math.radians(10.0))
    assert both_lines.status == "disagree"


def test_two_gravities_from_lines_that_disagree_refuse_the_motion():
    """Neither photo's gravity was given and they are far apart beyond their sigmas: the
    motion is refused with the reason rather than lifted on a gravity that is wrong."""
    R = _yaw(45.0)
    m = _matches(_points(seed=8), R, np.zeros(3))
    pa = pair.Photo(CAM.with_gravity(gravity_of(30.0, 0.0)), H, gravity_sigma=math.radians(1.0))
    pb = pair.Photo(CAM.with_gravity(gravity_of(-10.0, 0.0)), H,
                    gravity_sigma=math.radians(10.0))
    with pytest.raises(MotionError, match="disagree on which way is down.*give the phone's"):
        pair.agreed_gravity(pa, pb, m)
