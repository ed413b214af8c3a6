"""Gravity from the image (findme_core.single.vanishing) on rendered rooms with exact gravity."""

import math

import cv2
import numpy as np
import pytest

from findme_core.geometry.camera import Camera
from findme_core.single.vanishing import GravityParams, estimate_gravity, level_estimate
from findme_core.synth.render import Box, Pose, Room, render


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
    """Only the intrinsics are used: a camera that claims level changes nothing. (A cabinet
    on a plank floor: its vertical edges, seen at the shared half-scale detection, leave
    ~0.6 deg; the clean rooms above stay within 0.3.)"""
    cam = box_view.camera
    level = Camera(cam.fx, cam.fy, cam.cx, cam.cy, cam.width, cam.height)
    a, b = estimate_gravity(box_view.image, cam), estimate_gravity(box_view.image, level)
    assert np.allclose(a.vector, b.vector) and angle_deg(a.vector, cam.gravity) < 1.0


def test_a_large_photo_is_estimated_at_the_working_size(tilted_view):
    big = cv2.resize(tilted_view.image, (1920, 1440), interpolation=cv2.INTER_CUBIC)
    est = estimate_gravity(big, tilted_view.camera.scaled(3.0))
    assert angle_deg(est.vector, tilted_view.camera.gravity) < 0.5


def test_no_lines_means_level_assumed_and_said():
    blank = np.full((480, 640, 3), 128, np.uint8)
    est = estimate_gravity(blank, Camera.from_hfov(65, 640, 480))
    assert est.source == "level" and "level assumed" in est.reason
    assert np.allclose(est.vector, (0, 1, 0))
    # as wide as hand-held photos are tilted: pitch on its own axis, roll on its own
    sp, sr = GravityParams().level_sigma_deg
    np.testing.assert_allclose(np.degrees(np.sqrt(np.diag(est.cov))), (sp, sr))
    assert est.cov[0, 1] == 0 and sp > 20.0


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


def test_the_estimate_carries_its_segments_and_reuses_given_ones(tilted_view):
    from findme_core.single.segments import photo_segments
    segs = photo_segments(tilted_view.image)
    a = estimate_gravity(tilted_view.image, tilted_view.camera)
    b = estimate_gravity(tilted_view.image, tilted_view.camera, segments=segs)
    assert a.segments is not None and np.allclose(a.segments.segs, segs.segs)
    assert b.segments is segs and np.allclose(a.vector, b.vector)
    blank = estimate_gravity(np.full((480, 640, 3), 90, np.uint8), Camera.from_hfov(65, 640, 480))
    assert blank.source == "level" and blank.segments is not None   # level keeps them too


def _floor_case():
    """Exact segments of a room seen by a tilted camera (walls above row 250), floor
    stripes in a direction 30 deg off the walls below row 270, and the true frame."""
    from tests.core.geometry.test_manhattan import CAM, manhattan_lines, project, true_frame
    from findme_core.geometry.manhattan import level_axes
    R = true_frame(28.0, 2.0, 15.0)
    segs, _ = manhattan_lines(R, (8, 12, 12), seed=5)
    segs = segs[np.maximum(segs[:, 1], segs[:, 3]) < 250]
    g = R[:, 1]
    xl, zl = level_axes(g[None])
    d = np.cos(np.radians(30)) * R[:, 0] + np.sin(np.radians(30)) * R[:, 2]
    stripes = []
    for x, z in ((-0.6, 1.5), (-0.1, 1.45), (0.4, 1.5), (0.8, 1.6)):
        c0 = 1.4 * g + x * xl[0] + z * zl[0]
        stripes.append(project(np.array([c0 - 0.25 * d, c0 + 0.25 * d])).ravel())
    stripes = np.array(stripes)
    assert (np.minimum(stripes[:, 1], stripes[:, 3]) > 270).all()
    assert (np.maximum(stripes[:, 1], stripes[:, 3]) < 480).all()
    return R, np.vstack([segs, stripes]), CAM


def test_with_floor_reestimates_without_the_floor_lines():
    from tests.core.geometry.test_manhattan import line_set, project
    from findme_core.single.floor_gravity import with_floor
    from findme_core.single.vanishing import GravityEstimate
    R, segs, cam = _floor_case()
    off, _ = cv2.Rodrigues(np.radians([2.0, 0.0, 1.5]).reshape(3, 1))
    g0 = off @ R[:, 1]

    def est_of(s):
        return GravityEstimate(g0, np.eye(2) * 1e-4, "image", (8, 20), None, None,
                               (line_set(s), cam.K, 1.0))
    est = est_of(segs)
    boundary = np.array([[0.0, 260.0], [639.0, 260.0]])
    new = with_floor(est, boundary)
    assert new is not est and new.source == "image"
    assert angle_deg(new.vector, R[:, 1]) < 0.05
    # nothing on the floor: nothing to re-estimate
    assert with_floor(est, np.array([[0.0, 479.0], [639.0, 479.0]])) is est
    # something stands in the floor region (a vertical post there): not the floor's edge
    foot = 1.4 * R[:, 1] + np.array([0.0, 0.0, 1.6])
    post = project(np.array([foot, foot - 0.9 * R[:, 1]])).ravel()
    assert min(post[1], post[3]) > 270
    est2 = est_of(np.vstack([segs, post]))
    assert with_floor(est2, boundary) is est2
    # a level assumption is not re-estimated
    lev = level_estimate("no lines")
    assert with_floor(lev, boundary) is lev
