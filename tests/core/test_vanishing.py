"""Gravity from the image (findme_core.vanishing) on rendered rooms with exact gravity."""

import math

import cv2
import numpy as np
import pytest

from findme_core.camera import Camera
from findme_core.synth import Box, Pose, Room, render
from findme_core.vanishing import GravityParams, estimate_gravity, level_estimate


def angle_deg(a, b):
    return math.degrees(math.acos(float(np.clip(np.dot(a, b), -1, 1))))


@pytest.mark.parametrize("pose,hfov", [
    (Pose(0.3, -1.5, 1.45, yaw_deg=25.0), 80.0),                                  # level
    (Pose(-0.4, -1.8, 1.4, yaw_deg=-20.0, pitch_deg=30.0, roll_deg=4.0), 70.0),   # phone-like
    (Pose(-0.4, -1.8, 1.4, yaw_deg=30.0, pitch_deg=15.0, roll_deg=-6.0), 70.0),
])
def test_gravity_of_rendered_rooms(room, pose, hfov):
    v = render(room, pose, 640, 480, hfov_deg=hfov, seed=2)
    est = estimate_gravity(v.image, v.camera)
    assert est.source == "image" and est.reason is None
    assert sum(est.lines) >= 4
    err = angle_deg(est.vector, v.camera.gravity)
    assert err < 0.3, err
    assert 0 < math.degrees(est.sigma) < 2.0          # small, but never zero
    assert est.cov.shape == (2, 2) and np.all(np.linalg.eigvalsh(est.cov) > 0)


def test_gravity_ignores_the_cameras_own_gravity(box_view):
    """Only the intrinsics are used: a camera that claims level changes nothing."""
    cam = box_view.camera
    level = Camera(cam.fx, cam.fy, cam.cx, cam.cy, cam.width, cam.height)
    a, b = estimate_gravity(box_view.image, cam), estimate_gravity(box_view.image, level)
    assert np.allclose(a.vector, b.vector) and angle_deg(a.vector, cam.gravity) < 0.3


def test_a_large_photo_is_estimated_at_the_working_size(tilted_view):
    big = cv2.resize(tilted_view.image, (1920, 1440), interpolation=cv2.INTER_CUBIC)
    est = estimate_gravity(big, tilted_view.camera.scaled(3.0))
    assert angle_deg(est.vector, tilted_view.camera.gravity) < 0.5


def test_no_lines_means_level_assumed_and_said():
    blank = np.full((480, 640, 3), 128, np.uint8)
    est = estimate_gravity(blank, Camera.from_hfov(65, 640, 480))
    assert est.source == "level" and "level assumed" in est.reason
    assert np.allclose(est.vector, (0, 1, 0))
    assert math.degrees(est.sigma) == pytest.approx(GravityParams().level_sigma_deg)


def test_one_line_cannot_tell_gravity():
    img = np.full((480, 640, 3), 200, np.uint8)
    cv2.line(img, (40, 300), (600, 340), (20, 20, 20), 3)
    est = estimate_gravity(img, Camera.from_hfov(65, 640, 480))
    assert est.source == "level" and est.reason


def test_upside_down_photo_is_outside_the_prior(tilted_view):
    """A photo turned 180 deg has gravity pointing up the image: outside the tilt of a
    hand-held upright photo, so the estimate must not return an upside-down gravity."""
    est = estimate_gravity(cv2.rotate(tilted_view.image, cv2.ROTATE_180), tilted_view.camera)
    pitch = math.degrees(math.asin(est.vector[2]))
    roll = math.degrees(math.atan2(est.vector[0], est.vector[1]))
    p = GravityParams()
    assert est.vector[1] > 0 and p.pitch_range[0] <= pitch <= p.pitch_range[1]
    assert p.roll_range[0] <= roll <= p.roll_range[1]


def test_level_estimate():
    e = level_estimate("because", 5.0)
    assert e.source == "level" and e.reason == "because"
    assert math.degrees(e.sigma) == pytest.approx(5.0)
