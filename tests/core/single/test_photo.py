"""A photo without gravity to its hypotheses (findme_core.single.photo) on rendered rooms."""

import math

import numpy as np

from findme_core.single.methods import hypothesize
from findme_core.single.photo import hypothesize_estimated, hypothesize_without_gravity
from findme_core.single.vanishing import estimate_gravity, level_estimate


def angle_deg(a, b):
    return math.degrees(math.acos(float(np.clip(a @ b, -1, 1))))


def test_gravity_and_hypotheses_from_one_detection(tilted_view):
    v = tilted_view
    ticks = iter(range(1000))
    hs, est = hypothesize_without_gravity(v.image, v.camera, clock=lambda: float(next(ticks)))
    assert est.source == "image" and angle_deg(est.vector, v.camera.gravity) < 0.3
    # the same as the hypotheses of the photo given that gravity and those segments
    ref = hypothesize(v.image, v.camera.with_gravity(est.vector), segments=est.segments)
    assert len(hs.hypotheses) == len(ref.hypotheses)
    assert all(np.allclose(a.polyline, b.polyline) for a, b in zip(hs.hypotheses, ref.hypotheses))
    # and close to the hypotheses under the true gravity
    true = hypothesize(v.image, v.camera)
    a, b = hs.hypotheses[0].polyline, true.hypotheses[0].polyline
    cols = np.arange(640.0)
    assert np.abs(np.interp(cols, a[:, 0], a[:, 1]) - np.interp(cols, b[:, 0], b[:, 1])).mean() < 2.0
    assert list(hs.timing_ms)[:2] == ["gravity", "lines"] and "gravity_floor" in hs.timing_ms


def test_level_assumed_when_the_photo_cannot_tell():
    blank = np.full((480, 640, 3), 120, np.uint8)
    from findme_core.geometry.camera import Camera
    hs, est = hypothesize_without_gravity(blank, Camera.from_hfov(65, 640, 480))
    assert est.source == "level" and est.reason and hs.hypotheses == [] and hs.reason


def test_a_level_estimate_is_kept(tilted_view):
    """An estimate that is not from the image is not refined by the boundary."""
    est = level_estimate("assumed")
    hs, out = hypothesize_estimated(tilted_view.image, tilted_view.camera, est)
    assert out is est and np.allclose(out.vector, (0, 1, 0))
    first = estimate_gravity(tilted_view.image, tilted_view.camera)
    _, again = hypothesize_estimated(tilted_view.image, tilted_view.camera, first)
    assert angle_deg(again.vector, tilted_view.camera.gravity) < 0.3
