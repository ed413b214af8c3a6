"""Spots found from the photos (``session.auto_spots``) on a room the project renders: a
turn with a gap of left-out views is still one spot, and a photo taken elsewhere is not.

The zind-rooms sessions drop views that see too little floor, so a turn's consecutive
photos need not overlap; before, only consecutive photos were compared and such a spot was
split in two, each part placed on its own (dev: zr_r10's p17 turn flipped by 180 deg).
"""

import math
from types import SimpleNamespace

import numpy as np
import pytest

from findme_core.motion import features
from findme_core.plan import session
from findme_core.synth.room import Pose, Room
from findme_core.synth.render import render

H = 1.4


def _photos(poses):
    out = []
    for p in poses:
        v = render(Room.rectangle(5.0, 4.0), p, 640, 480, hfov_deg=70.0, supersample=1)
        out.append(SimpleNamespace(camera=v.camera, features=features.detect(v.image)))
    return out


def _match(photos):
    return lambda i, j: features.match(photos[i].features, photos[j].features)


@pytest.fixture(scope="module")
def turn_with_gaps():
    # spot A: 0, 50, then 180 (overlaps neither), then 330 (overlaps only the first photo);
    # spot B, 1.8 m away: two overlapping photos
    a = [Pose(-0.8, -0.5, H, y, 25.0, 0.0) for y in (0.0, 50.0, 180.0, 330.0)]
    b = [Pose(1.0, 0.6, H, y, 25.0, 0.0) for y in (100.0, 150.0)]
    return _photos(a + b), a + b


def test_a_turn_with_gaps_is_one_spot(turn_with_gaps):
    photos, poses = turn_with_gaps
    lab, links = session.auto_spots(photos, _match(photos))
    assert lab == [0, 0, 0, 0, 1, 1]
    # the links found are the true turns (the 180 deg photo is joined by the spot's end)
    for k in links:
        true = math.radians(poses[k.j].yaw_deg - poses[k.i].yaw_deg)
        assert abs(np.angle(np.exp(1j * (k.yaw - true)))) < math.radians(0.5)
    assert {(k.i, k.j) for k in links} == {(0, 1), (0, 3), (4, 5)}


def test_only_consecutive_photos_would_split_it(turn_with_gaps):
    # the photos' overlaps: 0-1, 0-3 and 4-5 only (what makes the test above a real test)
    photos, _ = turn_with_gaps
    from findme_core.plan import spot
    m = _match(photos)
    turned = {(i, j) for i in range(6) for j in range(i + 1, 6)
              if spot.rotation_yaw(m(i, j), photos[i].camera, photos[j].camera) is not None}
    assert turned == {(0, 1), (0, 3), (4, 5)}


def test_no_photo_and_one_photo():
    assert session.auto_spots([], None) == ([], [])
    photos = _photos([Pose(0.0, 0.0, H, 0.0, 25.0, 0.0)])
    assert session.auto_spots(photos, _match(photos)) == ([0], [])


def _tilted(cam, dpitch, droll):
    from findme_core.geometry.manhattan import gravity_of, pitch_roll_deg
    p, r = pitch_roll_deg(cam.gravity)
    return cam.with_gravity(gravity_of(p + dpitch, r + droll))


def test_a_turn_is_found_when_the_photos_gravities_disagree(turn_with_gaps):
    """A phone's gravity is never exact: B's 1.5 deg off moves its bearings ~12 px, and the
    yaw alone finds no turn; the whole rotation does, with the true yaw."""
    from findme_core.plan import spot
    photos, poses = turn_with_gaps
    m = features.match(photos[0].features, photos[1].features)
    cam_a, cam_b = photos[0].camera, _tilted(photos[1].camera, 1.2, -0.9)
    assert spot._yaw_only(*_level(m, cam_a, cam_b), spot.SpotParams()) is None
    found = spot.rotation_yaw(m, cam_a, cam_b)
    true = math.radians(poses[1].yaw_deg - poses[0].yaw_deg)
    assert found is not None and found.inliers >= 10 and found.rms_px < 2.0
    # B's level frame is itself off by its tilt: ~ droll sin(pitch) = 0.4 deg leaks into yaw
    assert abs(np.angle(np.exp(1j * (found.yaw - true)))) < math.radians(0.6)
    # two spots stay apart (parallax), and a tilt beyond the tolerance is not a turn
    for i, j in ((0, 4), (1, 5)):
        mm = features.match(photos[i].features, photos[j].features)
        assert spot.rotation_yaw(mm, photos[i].camera, _tilted(photos[j].camera, 1.0, 0.5)) is None
    assert spot.rotation_yaw(m, cam_a, _tilted(photos[1].camera, 4.0, 0.0)) is None


def _level(m, cam_a, cam_b):
    from findme_core.plan import spot
    ba, bb = spot._bearings(cam_a, m.ua), spot._bearings(cam_b, m.ub)
    yaws = np.arctan2(ba[:, 0], ba[:, 2]) - np.arctan2(bb[:, 0], bb[:, 2])
    return ba, bb, yaws, spot.SpotParams().residual_px / cam_a.fx
