import math

import numpy as np
import pytest

from findme_core.geometry.camera import Camera
from findme_core.errors import CameraError


def test_from_hfov_focal_and_centre():
    c = Camera.from_hfov(90.0, 640, 480)
    assert c.fx == pytest.approx(320.0) and c.fy == pytest.approx(320.0)
    assert (c.cx, c.cy) == (319.5, 239.5)
    # the border pixel's edge (u = -0.5) is at 45 degrees
    r = c.rays_cam([(-0.5, c.cy)])[0]
    assert math.degrees(math.atan2(-r[0], r[2])) == pytest.approx(45.0, abs=0.1)


def test_level_frame_of_level_camera_is_identity():
    c = Camera.from_hfov(60, 640, 480)
    assert np.allclose(c.R_level_from_cam, np.eye(3))
    assert c.is_level and c.pitch_deg == 0 and c.roll_deg == 0


@pytest.mark.parametrize("pitch,roll", [(30, 0), (0, 10), (25, -7), (-10, 3)])
def test_level_frame_axes(pitch, roll):
    p, r = math.radians(pitch), math.radians(roll)
    g = np.array([math.sin(r) * math.cos(p), math.cos(r) * math.cos(p), math.sin(p)])
    c = Camera.from_hfov(70, 640, 480, g)
    R = c.R_level_from_cam
    assert np.allclose(R @ R.T, np.eye(3), atol=1e-12) and np.linalg.det(R) == pytest.approx(1)
    assert np.allclose(R @ c.gravity, [0, 1, 0])            # gravity is level y
    fwd = R @ np.array([0, 0, 1.0])                          # optical axis: no x, forward z
    assert abs(fwd[0]) < 1e-12 and fwd[2] > 0
    assert c.pitch_deg == pytest.approx(pitch) and c.roll_deg == pytest.approx(roll)


def test_gravity_is_normalised_and_validated():
    c = Camera.from_hfov(60, 640, 480, (0, 2, 0))
    assert np.allclose(c.gravity, [0, 1, 0])
    for bad in [(0, 0, 0), (0, float("nan"), 1), (1, 2)]:
        with pytest.raises(CameraError, match="gravity"):
            Camera.from_hfov(60, 640, 480, bad)
    with pytest.raises(CameraError, match="straight down"):
        Camera.from_hfov(60, 640, 480, (0, 0, 1))


@pytest.mark.parametrize("kw,msg", [({"fx": -1.0}, "positive"), ({"width": 1}, "at least 2x2"),
                                    ({"cx": float("inf")}, "finite")])
def test_bad_intrinsics(kw, msg):
    args = dict(fx=500.0, fy=500.0, cx=320.0, cy=240.0, width=640, height=480)
    args.update(kw)
    with pytest.raises(CameraError, match=msg):
        Camera(**args)


def test_bad_hfov():
    with pytest.raises(CameraError, match="field of view"):
        Camera.from_hfov(180, 640, 480)


def test_horizon_and_vertical_vanishing_point():
    g = np.array([0.0, math.cos(0.4), math.sin(0.4)])  # looking down
    c = Camera.from_hfov(70, 640, 480, g)
    l = c.horizon_line()
    # pixels below the horizon have a downward level ray, above an upward one
    for u, v in [(10, 470), (600, 300), (320, -400)]:
        y = c.rays_level([(u, v)])[0, 1]
        assert np.sign(l @ [u, v, 1]) == np.sign(y)
    vp = c.vertical_vanishing_point()
    vp = vp[:2] / vp[2]
    assert vp[1] > 480  # the floor's vanishing point is below the image
    up = c.up_direction([(100, 100)])[0]
    assert up[1] < 0    # up points up the image


def test_projection_round_trip_and_scaling():
    c = Camera(500, 510, 300.2, 241.7, 640, 480, (0.1, 1, 0.3))
    px = np.array([[0, 0], [639, 479], [123.4, 56.7]])
    P = c.rays_cam(px) * 3.7
    uv, front = c.project_cam(P)
    assert front.all() and np.allclose(uv, px)
    s = c.scaled(0.5)
    assert (s.width, s.height) == (320, 240)
    # the same scene point lands on the scaled pixel: u_s = (u + 0.5) * s - 0.5
    uv2, _ = s.project_cam(P)
    assert np.allclose(uv2, (px + 0.5) * 0.5 - 0.5)
