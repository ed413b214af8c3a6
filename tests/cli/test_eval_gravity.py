"""How ``findme eval`` hands a view's gravity to the estimator (``evaluate.GravityInput``):
as it is, refined by the photo's lines, with a simulated sensor error, or withheld; on a
view the project renders (no dataset needed)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from findme.evaluation.views import GravityInput, view_camera
from findme_core.errors import InputError


def _meta(view, vid="zt_r01_p1_v0"):
    c = view.camera
    return {"id": vid, "gravity_cam": [float(g) for g in c.gravity],
            "intrinsics": {"fx": c.fx, "fy": c.fy, "cx": c.cx, "cy": c.cy,
                           "width": c.width, "height": c.height}, "camera_height_m": 1.4}


def _angle(a, b):
    return math.degrees(math.acos(float(np.clip(np.dot(a, b), -1.0, 1.0))))


def test_the_simulated_sensor_is_seeded_by_the_view_id(tilted_view):
    meta, g = _meta(tilted_view), GravityInput(noise_deg=1.5)
    a, sigma = g.of(meta)
    assert sigma is None                        # declared: the services' default
    np.testing.assert_array_equal(a, g.of(meta)[0])                  # the same every run
    assert not np.allclose(a, g.of(_meta(tilted_view, "zt_r01_p1_v1"))[0])   # per view
    errs = [_angle(g.of(_meta(tilted_view, f"v{k}"))[0], tilted_view.camera.gravity)
            for k in range(200)]
    # N(0, 1.5 deg) on pitch and on roll: the angle is Rayleigh-like, median ~1.5 * 1.18
    assert 1.2 < float(np.median(errs)) < 2.4 and max(errs) < 8.0
    assert GravityInput().of(meta)[0] == meta["gravity_cam"]          # no noise: as given
    assert GravityInput(sigma_deg=0.0).of(meta)[1] == 0.0
    assert GravityInput(given=False).of(meta) == (None, None)


def test_the_view_camera_as_it_is_refined_or_withheld(tilted_view):
    meta, truth = _meta(tilted_view), tilted_view.camera.gravity
    image = tilted_view.image
    cam, prov = view_camera(meta, image)                    # default: as it is (exact)
    assert prov.gravity == "input" and prov.estimate is None
    np.testing.assert_allclose(cam.gravity, truth, atol=1e-12)
    noisy = GravityInput(noise_deg=2.0, sigma_deg=2.0)
    cam, prov = view_camera(meta, image, noisy)
    off = _angle(cam.gravity, truth)
    cam, prov = view_camera(meta, image, GravityInput(noise_deg=2.0, sigma_deg=2.0, refine=True))
    assert prov.gravity == "input+image" and _angle(cam.gravity, truth) < min(0.5, off)
    cam, prov = view_camera(meta, image, False)
    assert prov.gravity == "image" and _angle(cam.gravity, truth) < 0.5


@pytest.mark.parametrize("kw", [{"noise_deg": -1.0}, {"sigma_deg": float("nan")},
                                {"noise_deg": 30.0}])
def test_bad_gravity_settings_are_named(kw):
    with pytest.raises(InputError, match="gravity"):
        GravityInput(**kw)


def test_the_predictions_say_how_gravity_was_given():
    assert GravityInput().describe() == "given, declared 1-sigma 0.5 deg"
    assert GravityInput(given=False).describe().startswith("withheld")
    assert GravityInput(noise_deg=1.5, sigma_deg=1.5, refine=True).describe() == (
        "given with simulated sensor noise N(0, 1.5 deg) per axis, declared 1-sigma 1.5 deg, "
        "combined with the image's vanishing directions")
