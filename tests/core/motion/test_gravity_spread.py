"""A gravity from a photo's lines reaches its motion's sigma: the motion estimated again with
the gravity tilted by its 1-sigma (``gravity_spread``); another motion found so widens it,
the same motion does not; a sensor's gravity is left to the model errors."""

from __future__ import annotations

import math

import cv2
import numpy as np
import pytest

from findme_core.geometry.camera import Camera
from findme_core.geometry.manhattan import gravity_of, pitch_roll_deg
from findme_core.motion import gravity_spread as gs
from findme_core.motion import pair
from findme_core.motion.photo_lines import photo_lines
from findme_core.motion.model import PlanarMotion
from findme_core.single.photo import hypothesize_without_gravity
from findme_core.synth.render import render
from findme_core.synth.room import Pose, Room

H = 1.4
S = math.radians(0.5)


def _motion(x=0.0, z=1.0, yaw=0.0, sx=0.05, sz=0.05, syaw=0.01, agree=3) -> PlanarMotion:
    """A motion with ``agree`` of its 60 matches agreeing with it (60: every one)."""
    return PlanarMotion(x, z, yaw, 0.0, sx, sz, syaw, np.arange(60) < agree, 3, "findme")


@pytest.mark.parametrize("axis,moved", [(0, 0), (1, 1)])
def test_tilted_turns_the_gravity_about_one_level_axis(axis, moved):
    cam = Camera(500.0, 500.0, 320.0, 240.0, 640, 480, gravity=gravity_of(0.0, 0.0))
    pitch_roll = pitch_roll_deg(gs.tilted(cam, axis, math.radians(2.0)))
    assert abs(abs(pitch_roll[moved]) - 2.0) < 1e-9 and abs(pitch_roll[1 - moved]) < 1e-9


def test_tilted_turns_a_tilted_camera_by_the_angle():
    cam = Camera(500.0, 500.0, 320.0, 240.0, 640, 480, gravity=gravity_of(30.0, -4.0))
    for axis in (0, 1):
        g = gs.tilted(cam, axis, math.radians(1.5))
        angle = math.degrees(math.acos(np.clip(g @ cam.gravity, -1.0, 1.0)))
        assert abs(angle - 1.5) < 1e-6


@pytest.mark.parametrize("sigmas", [(None, None), (math.inf, 0.0), (None, math.nan)])
def test_a_sensors_or_an_assumed_gravity_is_not_tilted(sigmas):
    calls, m = [], _motion()
    s = gs.spread(m, sigmas, lambda *a: calls.append(a))
    assert not calls and not s.tilts and not s.var.any()
    assert gs.widened(m, s) is m


def test_the_same_motion_under_every_tilt_adds_nothing():
    m = _motion()
    s = gs.spread(m, (S, S), lambda i, axis, a: _motion(x=0.05, yaw=math.radians(1.0)))
    assert len(s.tilts) == 8 and s.failed == 0 and not s.others(m)
    assert not s.var.any() and gs.widened(m, s) is m


def test_another_motion_on_one_side_adds_half_its_square():
    """Photo B's roll tilted by +s puts B 1 m to the side and 20 deg turned: a jump on one
    side of one axis adds half its square; tilts with no motion are counted, add nothing."""
    m = _motion()

    def under(i, axis, angle):
        if (i, axis) == (1, 1):
            return _motion(x=1.0, yaw=math.radians(20.0)) if angle > 0 else None
        return m

    s = gs.spread(m, (S, S), under)
    assert s.failed == 1 and [(t.photo, t.axis, t.angle) for t in s.others(m)] == [(1, 1, S)]
    np.testing.assert_allclose(s.var, [0.5, 0.0, math.radians(20.0) ** 2 / 2])
    w = gs.widened(m, s)
    assert w.sigma_x == pytest.approx(math.sqrt(0.05 ** 2 + 0.5))
    assert w.sigma_z == m.sigma_z and (w.x, w.z, w.yaw) == (m.x, m.z, m.yaw)


@pytest.mark.parametrize("agree,counted", [(30, False), (52, True), (60, True)])
def test_another_motion_fewer_matches_agree_with_is_ruled_out(agree, counted):
    """The answer has 60 agreeing matches. A tilt's other motion that 30 agree with is ruled
    out by the photos' matches (60 - 30 > sqrt(90)): it widens nothing; one that 52 agree
    with is within the counts' standard error (8 < sqrt(112)) and widens it."""
    m = _motion(agree=60)
    s = gs.spread(m, (S, None), lambda i, axis, a: (
        _motion(x=1.0, agree=agree) if (axis, a > 0) == (0, True) else m))
    assert len(s.tilts) == 4 and s.tilts[0].motion.x == 1.0
    assert s.tilts[0].another is counted
    np.testing.assert_allclose(s.var, [0.5 if counted else 0.0, 0.0, 0.0])


def test_a_turn_across_the_half_turn_is_the_short_way_round():
    m = _motion(yaw=math.radians(179.0))
    s = gs.spread(m, (S, None), lambda i, axis, a: _motion(yaw=math.radians(-179.0)))
    assert not s.others(m) and not s.var.any()   # 2 deg apart, not 358


@pytest.fixture(scope="module")
def walk():
    """Two plain photos 0.6 m apart in the rendered 5 x 4 m room, 30 deg down, no gravity
    given, as a camera app saves them: [(image, camera, gravity estimate, hypotheses)]."""
    out = []
    for x, yaw in ((0.3, 0.0), (-0.2, 20.0)):
        v = render(Room.rectangle(5.0, 4.0), Pose(x, -0.6, H, yaw, 30.0, 0.0), 640, 480,
                   hfov_deg=70.0, supersample=1)
        image = cv2.imdecode(cv2.imencode(".jpg", v.image, [cv2.IMWRITE_JPEG_QUALITY, 95])[1],
                             cv2.IMREAD_COLOR)
        cam = Camera(v.camera.fx, v.camera.fy, v.camera.cx, v.camera.cy, 640, 480)
        hs, est = hypothesize_without_gravity(image, cam, max_n=1, camera_height=H)
        out.append((image, cam, est, hs))
    return out


#: B in A's level frame: x, z (m), yaw (deg), as the walk's poses place it
TRUTH = (-0.5, 0.0, 20.0)


def _photos(walk, sensor: bool, roll_off_deg: float = 0.0):
    """The walk's photos on their lines' gravity (photo A's tilted ``roll_off_deg`` more in
    roll, as lines that are off would leave it), its 1-sigma a sensor's (None) or theirs."""
    out = []
    for k, (image, cam, est, hs) in enumerate(walk):
        c = cam.with_gravity(est.vector)
        if k == 0 and roll_off_deg:
            c = cam.with_gravity(gs.tilted(c, 1, math.radians(roll_off_deg)))
        out.append(pair.prepare(image, c, H, hs.hypotheses, 1, photo_lines(hs, image),
                                gravity_sigma=None if sensor else est.sigma))
    return out


def _z(m: PlanarMotion) -> np.ndarray:
    """|error| / 1-sigma of x, z and yaw against ``TRUTH``."""
    e = np.abs([m.x - TRUTH[0], m.z - TRUTH[1], math.degrees(m.yaw) - TRUTH[2]])
    return e / [m.sigma_x, m.sigma_z, math.degrees(m.sigma_yaw)]


def test_a_motion_on_gravities_from_lines_is_estimated_under_their_tilts(walk):
    """Photo A's lines leave its gravity +-5 deg unsure (B's +-1.7), and are right: tilted
    so, the motion is estimated again (8 tilts); A's roll turns the answer's 20 deg by 8 deg
    either way, but 130-180 fewer of the ~830 agreeing matches agree with those motions, so
    the matches rule them out and the answer keeps its 1-sigma (0.7 deg, a sensor's)."""
    res = pair.motion_photos(*_photos(walk, sensor=False))["findme"]
    sensor = pair.motion_photos(*_photos(walk, sensor=True))["findme"]
    assert sensor.gravity_spread is None
    s = res.gravity_spread
    assert len(s.tilts) == 8 and {(t.photo, t.axis) for t in s.tilts} == {
        (i, a) for i in (0, 1) for a in (0, 1)}
    assert [abs(t.angle) for t in s.tilts] == [walk[t.photo][2].sigma for t in s.tilts]
    m, m0 = res.motion, sensor.motion
    assert (m.x, m.z, m.yaw) == (m0.x, m0.z, m0.yaw)     # the answer as it was
    for k, name in enumerate(("sigma_x", "sigma_z", "sigma_yaw")):
        assert getattr(m, name) == pytest.approx(math.sqrt(getattr(m0, name) ** 2 + s.var[k]))
    rolled = [t for t in s.tilts if (t.photo, t.axis) == (0, 1)]
    assert all(abs(math.degrees(t.motion.yaw - m.yaw)) > 5.0 for t in rolled)
    assert all(t.motion.inliers.sum() < m.inliers.sum() - 100 for t in rolled)
    assert not s.others(m) and math.degrees(m.sigma_yaw) < 1.0
    assert np.all(_z(m) < 3.0)


def test_a_gravity_that_is_off_is_allowed_for_by_the_tilt_back(walk):
    """Photo A's gravity 4 deg off in roll (as KITTI's lines leave a road's): the answer
    turns 6-7 deg too far. Taken as a sensor's, its yaw says +-0.7 deg: many sigmas off. Its
    roll tilted back by its 1-sigma gives a motion as many matches agree with: that one
    counts, and the truth lies within the widened 1-sigma's 3."""
    sensor = pair.motion_photos(*_photos(walk, sensor=True, roll_off_deg=4.0))["findme"]
    res = pair.motion_photos(*_photos(walk, sensor=False, roll_off_deg=4.0))["findme"]
    m, s = res.motion, res.gravity_spread
    assert abs(math.degrees(m.yaw) - TRUTH[2]) > 5.0 and _z(sensor.motion)[2] > 5.0
    assert [(t.photo, t.axis, t.angle < 0) for t in s.others(m)] == [(0, 1, True)]
    assert abs(math.degrees(s.others(m)[0].motion.yaw) - TRUTH[2]) < 3.0
    assert np.all(_z(m) < 3.0) and math.degrees(m.sigma_yaw) > 5.0
