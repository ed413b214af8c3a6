"""A sensor's gravity combined with the photo's vanishing directions (gravity_fusion), on
rendered rooms whose gravity is exact and on the degenerate cases."""

import math

import numpy as np
import pytest

from findme_core.geometry.camera import Camera
from findme_core.errors import CameraError
from findme_core.single.gravity_fusion import FUSED, SENSOR, combine, level_axes, with_sensor
from findme_core.geometry.manhattan import gravity_of, pitch_roll_deg
from findme_core.single.photo import hypothesize_estimated
from findme_core.geometry.provenance import tilt_cov
from findme_io.camera_source import hypothesize_photo, with_gravity


def angle_deg(a, b):
    return math.degrees(math.acos(float(np.clip(np.dot(a, b), -1, 1))))


def tilted(g, dpitch, droll):
    p, r = pitch_roll_deg(g)
    return gravity_of(p + dpitch, r + droll)


# ------------------------------------------------------------------------ combine (exact)
def test_equal_measurements_meet_halfway_and_halve_the_variance():
    a, b = gravity_of(20.0, 1.0), gravity_of(22.0, 1.0)
    C = tilt_cov(math.radians(1.0))
    g, cov = combine(a, C, b, C)
    assert angle_deg(g, a) == pytest.approx(1.0, abs=0.01)
    assert angle_deg(g, b) == pytest.approx(1.0, abs=0.01)
    np.testing.assert_allclose(cov, C / 2)


def test_the_better_measurement_weighs_more_axis_by_axis():
    """Pitch known well by a, roll well by b: the result takes each axis from the one that
    knows it (covariances in the (pitch, roll) axes of the level frame; first order in the
    difference: 0.1 deg at 3 deg apart)."""
    a, b = gravity_of(20.0, 0.0), gravity_of(23.0, 3.0)
    ca = np.diag([math.radians(0.1), math.radians(5.0)]) ** 2
    cb = np.diag([math.radians(5.0), math.radians(0.1)]) ** 2
    g, cov = combine(a, ca, b, cb)
    p, r = pitch_roll_deg(g)
    assert p == pytest.approx(20.0, abs=0.1) and r == pytest.approx(3.0, abs=0.1)
    np.testing.assert_allclose(cov, np.linalg.inv(np.linalg.inv(ca) + np.linalg.inv(cb)))


def test_the_level_axes_are_pitch_forward_and_roll_right():
    z, x = level_axes(np.array([0.0, 1.0, 0.0]))
    np.testing.assert_allclose(z, [0, 0, 1], atol=1e-12)
    np.testing.assert_allclose(x, [1, 0, 0], atol=1e-12)
    with pytest.raises(CameraError, match="straight up or down"):
        level_axes(np.array([0.0, 0.0, 1.0]))


# ------------------------------------------------------------------- with_sensor (images)
@pytest.mark.parametrize("dpitch,droll", [(2.0, -1.5), (-1.0, 2.5)])
def test_a_wrong_sensor_is_pulled_to_the_truth(tilted_view, dpitch, droll):
    """A sensor 2.5-2.7 deg off, declared with 1.5 deg: the lines (within 0.3 deg of the truth
    on this room) pull the result within 0.5 deg, and its covariance is below both."""
    truth = tilted_view.camera.gravity
    sensor = tilted(truth, dpitch, droll)
    C = tilt_cov(math.radians(1.5))
    est = with_sensor(tilted_view.image, tilted_view.camera, sensor, C)
    assert est.source == FUSED and est.reason is None
    assert angle_deg(est.vector, truth) < 0.5 and angle_deg(sensor, truth) > 2.0
    assert np.all(np.linalg.eigvalsh(C - est.cov) > 0)
    assert est.prior[0] @ sensor == pytest.approx(1.0) and est.segments is not None


def test_an_exact_sensor_is_returned_as_it_is(tilted_view):
    g = tilted(tilted_view.camera.gravity, 1.0, 0.0)
    est = with_sensor(tilted_view.image, tilted_view.camera, 3 * g, np.zeros((2, 2)))
    assert est.source == SENSOR and "exact" in est.reason
    np.testing.assert_allclose(est.vector, g, atol=1e-12)


def test_a_photo_without_lines_keeps_the_sensor_and_says_why():
    blank = np.full((480, 640, 3), 128, np.uint8)
    g = gravity_of(25.0, 2.0)
    est = with_sensor(blank, Camera.from_hfov(65, 640, 480), g, tilt_cov(math.radians(1.0)))
    assert est.source == SENSOR and "sensor's gravity kept" in est.reason
    np.testing.assert_allclose(est.vector, g, atol=1e-12)
    assert math.degrees(math.sqrt(est.cov[0, 0])) == pytest.approx(1.0)


def test_a_photo_straight_down_keeps_the_sensor(tilted_view):
    est = with_sensor(tilted_view.image, tilted_view.camera, [0.0, 0.0, 1.0],
                      tilt_cov(math.radians(1.0)))
    assert est.source == SENSOR and "straight up or down" in est.reason


@pytest.mark.parametrize("sensor,cov,match", [
    ([0.0, 0.0, 0.0], tilt_cov(0.01), "non-zero"),
    ([0.0, float("nan"), 1.0], tilt_cov(0.01), "finite"),
    ([0.0, 1.0, 0.0], np.full((2, 2), np.nan), "covariance"),
    ([0.0, 1.0, 0.0], np.eye(3), "covariance"),
    ([0.0, 1.0, 0.0], np.diag([1e-4, 0.0]), "positive definite"),
])
def test_bad_sensor_inputs_are_named(tilted_view, sensor, cov, match):
    with pytest.raises(CameraError, match=match):
        with_sensor(tilted_view.image, tilted_view.camera, sensor, cov)


def test_the_floor_reestimate_is_combined_with_the_sensor_again(box_view):
    """After the boundary, ``with_floor`` re-estimates from the lines alone; the result is
    the sensor's prior combined with that, not the lines alone."""
    truth = box_view.camera.gravity
    sensor = tilted(truth, 1.5, 1.0)
    est = with_sensor(box_view.image, box_view.camera, sensor, tilt_cov(math.radians(1.5)))
    _, joint = hypothesize_estimated(box_view.image, box_view.camera, est)
    assert joint.source == FUSED and joint.prior is est.prior
    assert angle_deg(joint.vector, truth) < 0.6


# ------------------------------------------------------- the photo's camera (camera_source)
def test_a_given_gravity_is_refined_by_the_photo_unless_exact_or_not_estimated(tilted_view):
    cam, truth = tilted_view.camera, tilted_view.camera.gravity
    sensor = tilted(truth, -2.0, 1.0)
    c, prov = with_gravity(cam, tilted_view.image, sensor, math.radians(1.5))
    assert prov.gravity == "input+image" and prov.estimate is not None
    hs, c2, prov2 = hypothesize_photo(tilted_view.image, c, prov)
    assert hs.hypotheses and prov2.gravity == "input+image"
    assert angle_deg(c2.gravity, truth) < 0.5 and prov2.gravity_sigma < math.radians(1.5)
    for sigma, estimate in ((0.0, True), (math.radians(1.5), False)):
        c, prov = with_gravity(cam, tilted_view.image, sensor, sigma, estimate)
        assert prov.gravity == "input" and prov.estimate is None
        np.testing.assert_allclose(c.gravity, sensor / np.linalg.norm(sensor), atol=1e-12)
